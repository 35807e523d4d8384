"""Light Linking (Blender 4.0+, Object > Shading > Light Linking) as Cycles renders it.

A light with receivers lights only those objects directly; the rest of the scene still
sees it through other surfaces (indirect light is not linked). Cycles' scheme
(intern/cycles/kernel/light/light.h, depsgraph_light_linking.cc; docs/compatibility.md,
"linking38"): every object carries a receiver light set (0: the default, lit by every
light), every emitter a membership mask of the sets it lights, and

- next-event estimation at a surface lights it only from emitters whose mask holds the
  surface object's set (light_link_receiver_nee: the shaded object); the light tree is
  built per set (light_tree_root_node_index), so the others are never picked (here too:
  set_selector; where every light is sampled, their samples are zero);
- a BSDF-sampled ray that meets a lamp (MIS) takes its light only if the lamp lights the
  object the ray left (light_link_receiver_forward: mis_ray_object), with that set's
  tree probability in its MIS weight (tree_pmf); camera rays see every lamp
  (PATH_RAY_CAMERA);
- the photon map: a photon's first hit on an object its light does not link ends the
  photon there (not stored, not bounced), or the gather would carry light the object
  never received.

Here the sets are the distinct columns of the (emitters x meshes) table "emitter i lights
mesh m", so any number of them works (Cycles stops at 64). The emitters are the lamps and
the emitting meshes with links of their own (Mesh.receivers / non_receivers: an emitting
object's Light Linking); those meshes' triangles stay in the one mesh light, and their
links act per triangle: a set's packing zeroes their radiance (the triangle tree may
still pick them: a zero sample), a BSDF ray or a gather ray meeting one counts it only
if it lights the object the ray left, and a photon from one (its triangle known from its
emission number, photonkernels.uniform) ends at a first hit it does not light. The world
lights every object. A point in a volume takes the volume's set (volume_sets: a fog box's
object's; in the world volume, no object: Cycles' set 0, which an emitter with an include
list does not light).

Shadow Linking (Light.blockers / non_blockers): a light's shadow rays pass the objects
that are not its blockers (Cycles' intersection_skip_shadow_link, kernel/bvh/util.h: an
intersection is skipped when the object's blocker_shadow_set is not in the ray's light's
shadow_set_membership).
Lights with the same blockers form a shadow group; each group other than "every object
blocks" traces its shadow rays in its own BVH of its blockers' triangles (built once with
the scene, ShadowGroup), and direct light is summed group by group, each pass with the
other groups' lights zeroed. The light's photons are traced twice: as usual (a
non-blocker in their way receives them), then again keeping only those whose first hit
was a non-blocker, moved to the blocker behind it (past_non_blockers), so both are lit as
in Cycles (a second non-blocker behind the first gets none). A ray leaving a surface
meets such a lamp wherever it lies unless a blocker is between (integrator.
shadow_linked_rows; Cycles' dedicated shadow-linking ray), and goes on to its own hit.
"""
from __future__ import annotations

import numpy as np

from .lights import packing as pk


class LightLinks:
    """Which light lights which object, for a prepared scene.

    lit (L, M) bool: ctx.lights[i] lights scene.meshes[m] directly.
    mesh_set (M,) int64: each mesh's receiver set; sets (S, L) bool: the lights of each
    set, emit_sets (S, K): its emitting meshes with links (the distinct columns of lit
    stacked on emit_lit, in np.unique's order)."""

    def __init__(self, lit: np.ndarray, blocks: np.ndarray | None = None,
                 emit_lit: np.ndarray | None = None, emitters: np.ndarray | None = None):
        self.lit = np.ascontiguousarray(lit, np.bool_)
        L, M = self.lit.shape
        # Emitting meshes with links: emit_lit (K, M) mesh emitters[k] lights mesh m;
        # emit_row (M,) each mesh's row there (-1: no links of its own, lights every one).
        self.emit_lit = (np.ones((0, M), np.bool_) if emit_lit is None
                         else np.ascontiguousarray(emit_lit, np.bool_))
        self.emit_row = np.full(M, -1, np.int64)
        if emitters is not None:
            self.emit_row[np.asarray(emitters, np.int64)] = np.arange(len(emitters))
        table = np.concatenate([self.lit, self.emit_lit])
        cols = table.T
        uniq, inverse = np.unique(cols, axis=0, return_inverse=True) if len(cols) else (
            np.ones((1, len(table)), np.bool_), np.zeros(0, np.int64))
        self.sets = np.ascontiguousarray(uniq[:, :L], np.bool_)
        self.emit_sets = np.ascontiguousarray(uniq[:, L:], np.bool_)  # (S, K)
        self.mesh_set = np.asarray(inverse, np.int64).reshape(-1)
        # The mesh light's triangles' emitter rows (set by for_scene; None: none linked).
        self.mesh_tri_row = None
        # What lights a point in no object (the world volume: Cycles' OBJECT_NONE, set
        # 0): every emitter without an include list (set by for_scene).
        self.none_lit = np.ones(L, np.bool_)
        self.emit_none_lit = np.ones(len(self.emit_lit), np.bool_)
        self._material_set = None
        # Shadow Linking: blocks (L, M) light i's shadow rays are stopped by mesh m; the
        # shadow groups (ShadowGroup), made by build_shadow_groups.
        self.blocks = (np.ones_like(self.lit) if blocks is None
                       else np.ascontiguousarray(blocks, np.bool_))
        self.shadow_groups = []
        self._packs = {}

    @property
    def has_receivers(self) -> bool:
        return not self.lit.all()

    @property
    def has_blockers(self) -> bool:
        return not self.blocks.all()

    def build_shadow_groups(self, geo, accel_class, threads=1, should_cancel=None):
        """The shadow groups: for each distinct blockers row (lights blocked alike) a
        ShadowGroup; the lights blocked by every object trace in the scene's BVH
        (accel None). Needs geo.vertices32 / faces32 (before release_build_arrays)."""
        from .geometry import SHADOW
        self.shadow_groups = []
        if not self.has_blockers:
            return
        rows, inverse = np.unique(self.blocks, axis=0, return_inverse=True)
        inverse = np.asarray(inverse).reshape(-1)
        tri_object = np.asarray(geo.object_id, np.int64)
        casts = (np.asarray(geo.visibility) & SHADOW) != 0
        for g, row in enumerate(rows):
            lights = inverse == g
            if row.all():
                self.shadow_groups.append(ShadowGroup(lights, None))
                continue
            idx = np.nonzero(casts & row[tri_object])[0]
            self.shadow_groups.append(ShadowGroup(lights, BlockerAccel(
                geo.vertices32, geo.faces32, idx, accel_class, threads, should_cancel)))

    def blocker_accel(self, li: int):
        """The BlockerAccel of light li's shadow group (None: every object blocks it)."""
        for group in self.shadow_groups:
            if group.lights[li]:
                return group.accel
        return None

    def close(self, wait: bool = False):
        for group in self.shadow_groups:
            if group.accel is not None:
                group.accel.close(wait)

    @classmethod
    def for_scene(cls, scene, lights, geo=None) -> "LightLinks | None":
        """The links of the prepared lights (engine/lights/: a declared light's `source`,
        its scene Light, holds receivers, non_receivers, blockers and non_blockers), or
        None when no light is linked."""
        names = [m.name for m in scene.meshes]
        index = {}
        for m, name in enumerate(names):
            index.setdefault(name, []).append(m)
        M = len(names)

        def table(attr):
            rows, linked = [], False
            for light in lights:
                row = np.ones(M, np.bool_)
                source = getattr(light, "source", None)  # the scene Light (declared)
                only = getattr(source, attr, None)
                excl = getattr(source, "non_" + attr, None) or ()
                if only is not None:
                    row[:] = False
                    for name in only:
                        row[index.get(name, [])] = True
                    linked = True
                for name in excl:
                    if only is not None and name in only:
                        continue
                    row[index.get(name, [])] = False
                    linked = True
                rows.append(row)
            return np.array(rows, np.bool_).reshape(len(lights), M), linked

        lit, by_recv = table("receivers")
        blocks, by_block = table("blockers")
        # Emitting meshes' own Light Linking (Mesh.receivers / non_receivers).
        emitters, rows = [], []
        materials = getattr(scene, "materials", {})
        for m, mesh in enumerate(scene.meshes):
            only = getattr(mesh, "receivers", None)
            excl = getattr(mesh, "non_receivers", None) or ()
            if only is None and not excl:
                continue
            if not any(getattr(materials.get(name), "is_emissive", False)
                       for name in mesh.materials):
                continue  # (links of an object that emits nothing act on nothing)
            row = np.zeros(M, np.bool_) if only is not None else np.ones(M, np.bool_)
            for name in only or ():
                row[index.get(name, [])] = True
            for name in excl:
                if only is None or name not in only:
                    row[index.get(name, [])] = False
            emitters.append(m)
            rows.append(row)
        if not (by_recv or by_block or emitters):
            return None
        links = cls(lit, blocks, np.array(rows, np.bool_).reshape(len(rows), M),
                    np.array(emitters, np.int64))
        links.none_lit = np.array([getattr(getattr(light, "source", None), "receivers",
                                           None) is None for light in lights], np.bool_)
        links.emit_none_lit = np.array([scene.meshes[m].receivers is None
                                        for m in emitters], np.bool_)
        if emitters:
            for light in lights:
                tri = getattr(light, "tri_index", None)
                if getattr(light, "kind", "") == "MESH" and tri is not None and geo is not None:
                    links.mesh_tri_row = links.emit_row[object_of(geo, np.asarray(tri))]
        return links

    @property
    def has_emitters(self) -> bool:
        return len(self.emit_lit) > 0

    def emission_lights(self, geo, emit_prim: np.ndarray, from_prim: np.ndarray) -> np.ndarray:
        """(n,) bool: the emitting triangles emit_prim light the objects of triangles
        from_prim the rays left (True where from_prim < 0: the camera, or the emitter has
        no links of its own): Cycles' light_link_object_match for a BSDF or gather ray."""
        out = np.ones(len(emit_prim), np.bool_)
        if not self.has_emitters:
            return out
        emit_prim = np.asarray(emit_prim, np.int64)
        from_prim = np.asarray(from_prim, np.int64)
        ok = np.nonzero((emit_prim >= 0) & (from_prim >= 0))[0]
        if not len(ok):
            return out
        row = self.emit_row[object_of(geo, emit_prim[ok])]
        linked = row >= 0
        if linked.any():
            r = ok[linked]
            out[r] = self.emit_lit[row[linked], object_of(geo, from_prim[r])]
        return out

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

    def volume_sets(self, geo, medium_rows, world_row: int) -> np.ndarray:
        """(n,) int64 receiver sets of points in the media of material rows medium_rows
        (engine/volumescatter.py; Cycles' volume light sampling takes the volume
        object's set, light_link_receiver_nee): NO_OBJECT in the world volume
        (world_row; Cycles' OBJECT_NONE), the set of the objects whose material it is
        where they share one, else -1 (every light)."""
        if self._material_set is None:
            mat = np.asarray(geo.material, np.int64) if geo.shared is None else None
            n_rows = int(mat.max()) + 1 if mat is not None and len(mat) else 0
            table = np.full(max(n_rows, world_row + 1, 1), -1, np.int64)
            if mat is not None:
                obj_set = self.mesh_set[np.asarray(geo.object_id, np.int64)]
                for r in np.unique(mat):
                    sets = np.unique(obj_set[mat == r])
                    table[r] = sets[0] if len(sets) == 1 else -1
            self._material_set = table
        rows = np.asarray(medium_rows, np.int64)
        table = self._material_set
        out = np.where((rows >= 0) & (rows < len(table)),
                       table[np.clip(rows, 0, len(table) - 1)], -1)
        if world_row >= 0:
            out[rows == world_row] = NO_OBJECT
        return out

    def packed_for(self, packed, s: int, group: int = -1):
        """The packed lights (lights.packing.pack_lights) as receiver set s (-1: every
        light; NO_OBJECT: a point in no object) sees them, of shadow group `group` only (-1: every group): the other lights
        with zero colour, so the shadow-ray kernel makes no entry (and no ray) for their
        samples. Cached per packing."""
        key = (id(packed), int(s), int(group))
        hit = self._packs.get(key)
        if hit is not None and hit[0] is packed:
            return hit[1]
        codes, params, mesh = packed
        off = np.zeros(len(codes), np.bool_)
        if s >= 0:
            off |= ~self.sets[s]
        elif s == NO_OBJECT:
            off |= ~self.none_lit
        if group >= 0:
            off |= ~self.shadow_groups[group].lights
        if off.any():
            params = params.copy()
            params[off, pk.RGB:pk.RGB + 3] = 0.0
        rows = self.mesh_tri_row
        if (s >= 0 or s == NO_OBJECT) and rows is not None and \
                len(rows) == len(mesh[MESH_L]):
            # Emitting meshes with links: their triangles' radiance, where they do not
            # light set s, zeroed.
            lit = self.emit_sets[s] if s >= 0 else self.emit_none_lit
            dark = (rows >= 0) & ~lit[np.maximum(rows, 0)]
            if dark.any():
                m_L = mesh[MESH_L].copy()
                m_L[dark] = 0.0
                mesh = (*mesh[:MESH_L], m_L, *mesh[MESH_L + 1:])
        out = (codes, params, mesh)
        self._packs[key] = (packed, out)
        return out

    def direct(self, direct_light, packed, hit_arrays, samples, accel, shadow_cls, n, recv,
               rows=None, transmission=None, bsdf=None, passages=None, medium_sigma=None,
               world_sigma=None, tree=None, trees=None, used=None, **kw):
        """directlight.direct_light with Light and Shadow Linking (its `link`): the hits
        of each receiver set (recv (n,) int64, -1: none) with their own packing (and,
        when a light tree picks the lights, with trees(s): set_selector's tree of that
        set), and each shadow group's lights with its own BVH; the per-hit inputs taken
        at each set's rows (bsdf's fd and transmission's arrays count the hits; bsdf's
        prm, wo and sel are read at the rows; used too), the sums put back. Returns (E (n,3),
        shadow rays)."""
        sets = np.unique(recv)
        groups = list(range(len(self.shadow_groups))) or [-1]

        def tree_of(s):
            """The set's tree arrays (an empty tree where no member lights it: its picks
            give nothing, samples by light index still count)."""
            if tree is None or trees is None or s < 0:
                return tree
            ch = trees(int(s))
            if ch is None:
                return tree
            if ch[0] is None:
                from .lights.selection import empty_tree
                return (*empty_tree(), tree[4])
            return ch[1]

        if len(sets) == 1 and len(groups) == 1:
            t = tree_of(sets[0])
            return direct_light(self.packed_for(packed, int(sets[0])), hit_arrays, samples,
                                accel, shadow_cls, n, rows=rows, transmission=transmission,
                                bsdf=bsdf, passages=passages, medium_sigma=medium_sigma,
                                world_sigma=world_sigma, tree=t, used=used, **kw)
        out = np.zeros((n, 3))
        rays = 0
        hrow = np.arange(n, dtype=np.int64) if rows is None else np.asarray(rows, np.int64)

        def pick(a, sel):
            return None if a is None else np.ascontiguousarray(a[sel])

        for s in sets:
            t = tree_of(s)
            sel = np.nonzero(recv == s)[0]
            part = [(li, tr, cnt, pick(u1, sel), pick(u2, sel), pick(third, sel))
                    for li, tr, cnt, u1, u2, third in samples]
            b = None if bsdf is None else (pick(bsdf[0], sel), *bsdf[1:])
            # transmission's arrays count the hits (accumulate_transmission reads them by
            # the entries' hit index); the hit arrays are read at the rows.
            tr_ = None if transmission is None else (
                pick(transmission[0], sel), pick(transmission[1], sel),
                pick(transmission[2], sel), transmission[3], pick(transmission[4], sel))
            for g in groups:
                acc = accel if g < 0 or self.shadow_groups[g].accel is None \
                    else self.shadow_groups[g].accel
                E, r = direct_light(self.packed_for(packed, int(s), g), hit_arrays, part,
                                    acc, shadow_cls, len(sel), rows=hrow[sel],
                                    transmission=tr_, bsdf=b, passages=pick(passages, sel),
                                    medium_sigma=pick(medium_sigma, sel),
                                    world_sigma=pick(world_sigma, sel), tree=t,
                                    used=pick(used, sel), **kw)
                out[sel] += E
                rays += r
        return out, rays


# The packed mesh arrays' radiance (lights.packing.pack_lights: v0, e1, e2, ng, L, ...).
MESH_L = 4
# The receiver "set" of a point in no object (the world volume).
NO_OBJECT = -2


def mesh_photon_rows(links, light, key, slot: np.ndarray) -> np.ndarray:
    """(m,) int64 emitter rows (LightLinks.emit_row; -1: no links) of the triangles the
    mesh light's photons in `slot` left (meshphotons.emitted_triangles: emit_mesh's
    own pick)."""
    from .meshphotons import emitted_triangles
    return links.mesh_tri_row[emitted_triangles(light, key, slot)]


class ShadowGroup:
    """Lights (L,) bool blocked by the same objects, and the BVH of those (a
    BlockerAccel; None: every object, the scene's own BVH)."""

    def __init__(self, lights, accel):
        self.lights = np.asarray(lights, np.bool_)
        self.accel = accel


class BlockerAccel:
    """The shadow-ray BVH of a shadow group: the blockers' triangles idx only (those
    visible to shadow rays), answering occluded_into as VisibilityAccel does, and the
    closest blocker hit of photon rays (first_hits)."""

    def __init__(self, vertices32, faces32, idx, accel_class, threads, should_cancel):
        self.empty = len(idx) == 0
        self.idx = np.asarray(idx, np.int64)
        self.accel = None if self.empty else accel_class(
            vertices32, np.ascontiguousarray(faces32[idx]), threads=threads,
            should_cancel=should_cancel)

    def first_hits(self, o32, d32):
        """(rows (N,) int64 scene triangle rows of the closest blocker hit, -1: none;
        u, v (N,) float32; t (N,) float32 its distance) of float32 rays o32, d32."""
        n = len(o32)
        t = np.full(n, np.finfo(np.float32).max, np.float32)
        if self.empty or n == 0:
            return (np.full(n, -1, np.int64), np.zeros(n, np.float32),
                    np.zeros(n, np.float32), t)
        serial = self.accel.serial() if hasattr(self.accel, "serial") else self.accel
        geom, prim, u, v, starts = serial.intersect_hits(
            np.ascontiguousarray(o32, np.float32), np.ascontiguousarray(d32, np.float32), t)
        rows = np.full(n, -1, np.int64)
        ok = geom >= 0
        rows[ok] = self.idx[np.take(starts, geom[ok]) + prim[ok]]
        return rows, np.asarray(u, np.float32), np.asarray(v, np.float32), t

    def occluded_into(self, o32, d32, tmax32, blocked, cls=None):
        if self.empty:
            blocked[:] = False
            return blocked
        return self.accel.occluded_into(o32, d32, tmax32, blocked)

    def close(self, wait: bool = False):
        if self.accel is not None:
            self.accel.close(wait)


# set_selector's answer for a receiver set no light of the tree lights.
NO_LIGHTS = (None, None)
# One light tree per receiver set (Cycles' scheme); False: the scene's one tree, whose
# picks of a lamp that does not light the surface give zero (bench/bench_light_linking.py
# measures the difference).
PER_SET_TREES = True


def set_selector(ctx, s: int, skip_mesh_lights: bool = False):
    """The light tree of receiver set s: lights.selection.selector_for's (LightSelector,
    kernel arrays) over the members that light set s only, as Cycles builds a tree per
    light set (light_tree_root_node_index), so a surface never picks a lamp that gives it
    nothing (measured: bench/bench_light_linking.py); selector_for's own when every
    member lights s (or s < 0, no object); NO_LIGHTS when none does; None without a
    tree. Built once per context."""
    from .lights.selection import LightSelector, selector_for
    base = selector_for(ctx, skip_mesh_lights)
    links = getattr(ctx, "links", None)
    if base is None or links is None or s < 0 or not PER_SET_TREES:
        return base
    lit = links.sets[s]
    members = [int(li) for li in base[0].members if lit[li]]
    if len(members) == len(base[0].members):
        return base
    key = ("linked", bool(skip_mesh_lights), int(s))
    cache = ctx.light_selectors
    if key not in cache:
        if not members:
            cache[key] = NO_LIGHTS
        else:
            sel = LightSelector(ctx.lights, members)
            cache[key] = (sel, (sel.tree_f, sel.tree_i, sel.infinite, sel.inf_f, base[1][4]))
    return cache[key]


def tree_pmf(ctx, chosen, p, ns, li: int, sets=None) -> np.ndarray:
    """The light tree's probability (N,) of picking light li at points p (N,3) with
    shading normals ns (N,3) (LightSelector.pmf), for multiple importance sampling: with
    sets (N,) the receiver sets of the surfaces there (lightlinking), each set's own tree
    (set_selector), as their shadow rays pick; chosen = selector_for(ctx)."""
    if sets is None or getattr(ctx, "links", None) is None:
        return chosen[0].pmf(p, ns, li)
    p = np.asarray(p).reshape(-1, 3)
    ns = np.asarray(ns).reshape(-1, 3)
    out = np.zeros(len(p))
    for s in np.unique(sets):
        r = np.nonzero(sets == s)[0]
        ch = set_selector(ctx, int(s))
        if ch is not None and ch[0] is not None:
            out[r] = ch[0].pmf(p[r], ns[r], li)
    return out


class _LinkCall:
    """direct_light's `link` object for one call: LightLinks.direct with the light trees
    of the call's receiver sets (set_selector with the caller's skip_mesh_lights)."""

    def __init__(self, ctx, links, skip_mesh_lights):
        self.ctx, self.links, self.skip = ctx, links, skip_mesh_lights

    def direct(self, *args, **kw):
        return self.links.direct(*args, trees=lambda s: set_selector(self.ctx, s, self.skip),
                                 **kw)


def links_for(scene, lights, geo, accel, accel_class, threads=1, should_cancel=None):
    """The LightLinks of a prepared scene (None: no light linked), with its shadow
    groups' BVHs built (needs geo's build arrays); Shadow Linking is dropped with a
    scene warning where the scene's BVH is two-level (shared instances)."""
    links = LightLinks.for_scene(scene, lights, geo)
    if links is not None and links.has_blockers:
        if getattr(accel, "two_level", False):
            msg = ("Shadow Linking is not supported with shared instances (two-level "
                   "instancing); every object casts the linked lights' shadows")
            if msg not in scene.warnings:
                scene.warnings.append(msg)
            links.blocks[:] = True
        else:
            links.build_shadow_groups(geo, accel_class, threads, should_cancel)
    return links


def receiver_link(ctx, hit, rows=None, skip_mesh_lights: bool = False):
    """directlight.direct_light's link for the hits (at rows; None: all): (a call
    object whose direct() is LightLinks.direct with the receiver sets' light trees, the
    receiver set (n,) of each hit's object), or None when no light is linked (Cycles'
    light_link_receiver_nee: the shaded object). skip_mesh_lights: the tree the caller
    samples (lights.selection.selector_for's)."""
    links = getattr(ctx, "links", None)
    if links is None:
        return None
    prim = hit.prim if rows is None else np.take(hit.prim, rows)
    return _LinkCall(ctx, links, skip_mesh_lights), links.receiver_set(ctx.geo, prim)


def link_row_of(ctx, emitter):
    """(M,) bool: the objects a photon emitter (a light of ctx.lights or a
    lights.group.LightGroup of lights linked alike) lights; None: every object."""
    links = getattr(ctx, "links", None)
    if links is None:
        return None
    li = _light_index(ctx, emitter)
    if li is None:
        return None
    row = links.lit[li]
    return None if row.all() else row


def _light_index(ctx, emitter):
    """The index in ctx.lights of the light a photon emitter stands for (unwrapped; a
    light prepared from the same source counts), or None."""
    light = unwrapped(emitter)
    source = getattr(light, "source", None)
    for li, other in enumerate(ctx.lights):
        if other is light or (source is not None and other.source is source):
            return li
    return None


def unwrapped(emitter):
    """The light a photon emitter stands for: a group's first member, an aimed wrapper's
    light (visualimportance.RegionEmitter, portal.PortalEmitter: .light)."""
    light = emitter.lights[0] if hasattr(emitter, "lights") else emitter
    for _ in range(4):
        inner = getattr(light, "light", None)
        if inner is None:
            break
        light = inner
    return light


def blocker_accel_of(ctx, emitter):
    """The BlockerAccel of the shadow group of a photon emitter's light (Shadow Linking:
    its photons are traced a second time past the non-blockers), or None (blocked by
    every object, or no linking)."""
    links = getattr(ctx, "links", None)
    if links is None or not links.shadow_groups:
        return None
    li = _light_index(ctx, emitter)
    if li is None:
        return None
    for group in links.shadow_groups:
        if group.lights[li]:
            return group.accel
    return None


def past_non_blockers(past, o32, d32, geom, prim32, u, v, tfar32, starts):
    """The second photon run of a shadow-linked light (photons.trace_photons): a photon
    whose first hit is not one of the light's blockers (a non-blocker lies in front of
    the blocker `past` finds) moves to that blocker hit: geom, prim32, u, v, tfar32 (m,)
    rewritten in place in intersect_hits' layout with one geometry from row 0 (returned:
    the new starts); every other photon becomes a miss (it is the first run's). So the
    non-blocker gets its photons in the first run and what lies behind it gets them in
    this one, as Cycles lights both."""
    rows_b, u_b, v_b, t_b = past.first_hits(o32, d32)
    full = np.where(geom >= 0, np.take(starts, np.maximum(geom, 0)) + prim32, -1)
    passed = (rows_b >= 0) & (full != rows_b)
    geom[:] = np.where(passed, 0, -1)
    prim32[:] = np.where(passed, rows_b, 0)
    u[:] = np.where(passed, u_b, u)
    v[:] = np.where(passed, v_b, v)
    tfar32[:] = np.where(passed, t_b, tfar32)
    return np.zeros(1, np.int64)


def mesh_photon_links(ctx, emitter):
    """(links, the mesh light) when `emitter` is the mesh light and an emitting mesh has
    links of its own (its photons end per triangle: unlinked_first_hits' rows); else
    None."""
    links = getattr(ctx, "links", None)
    if links is None or links.mesh_tri_row is None or not (links.mesh_tri_row >= 0).any():
        return None
    light = unwrapped(emitter)
    return (links, light) if getattr(light, "kind", "") == "MESH" else None


def unlinked_first_hits(geo, link_row, geom, prim32, starts, emit_rows=None,
                        emit_lit=None) -> int:
    """Turn the photons' first hits on objects their light does not light into misses:
    geom (m,) int32 Embree geometry ids (-1: a miss) set to -1 there, in place. link_row
    (M,) bool: the objects the light lights (None: every one); or per photon emit_rows
    (m,) rows of emit_lit (K, M) (-1: every object). Returns how many."""
    ok = np.nonzero(geom >= 0)[0]
    if not len(ok):
        return 0
    prim = np.take(starts, geom[ok]).astype(np.int64) + prim32[ok]
    obj = object_of(geo, prim)
    if link_row is not None:
        lit = link_row[obj]
    else:
        rows = emit_rows[ok]
        lit = np.ones(len(ok), np.bool_)
        on = rows >= 0
        lit[on] = emit_lit[rows[on], obj[on]]
    cut = ok[~lit]
    geom[cut] = -1
    return len(cut)


def object_of(geo, prim: np.ndarray) -> np.ndarray:
    """Object (scene mesh) index of triangles prim >= 0, shared instances included."""
    rows, (object_id,) = geo.hit_tables(prim, "object_id")
    return np.take(object_id, rows).astype(np.int64)
