"""Pass 1: shoot photons from the lights, scatter them with Russian roulette, store hits.

Whole chunks of photons go through each bounce as arrays. At every hit on a surface with
a diffuse lobe the incoming photon is recorded with the kind of path that brought it:
  DIRECT   light -> this surface                  (direct light comes from shadow rays;
                                                   these photons serve final gathering)
  CAUSTIC  light -> specular+ -> this surface     (L S+ D: the caustic map)
  INDIRECT light -> ... diffuse ... -> surface    (the global map)
  CAUSTIC_DIFFUSE  light -> specular+ -> diffuse -> specular* -> surface: light from a
                   caustic, one diffuse bounce later. Final gathering would see the bright
                   caustic through few gather rays (fireflies), so these photons are
                   estimated directly instead and kept out of the gather map.
Russian roulette picks one lobe (diffuse, mirror, glass reflect / transmit, coat, pass)
with probability = the lobe's largest RGB weight, or absorbs; power is divided by that
probability, so the expected power is kept (the paper's scheme with pbrt's max rule,
which never increases a photon's power). Everything between two Embree calls runs in the
compiled kernels of engine/photonkernels.py, and so does emission (each light kind's
emit kernel, engine/lights/emission.py); this module drives the bounces.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from .anisotropy import triangle_tangents
from .lights.base import emission_key
from .lights.emission import EmissionBuffers
from .lights.group import photon_emitters
from .lightlinking import (blocker_accel_of, link_row_of, mesh_photon_links,
                           mesh_photon_rows, past_non_blockers, unlinked_first_hits)
from .parallel import Cancelled, chunk_length, ordered_map
from . import blurredpassage, media, photonclamp, photonmedium, worldmedium
from . import photonkernels as pk
from .accel import rows_as_hits
from .bsdf import LOBE_NAMES, surface_hit
from .coincident import CoincidentSurfaces
from .glossysplit import settings_filter_glossy
from .closures.principled import M_IOR
from .console import short_count
from .normalmap import bump_shadowing
from .shadelight import next_event_tri
from .mediumstart import point_medium
from .scene import AREA, POINT, SPOT
from .geometry import SHADOW
from .photonkernels import CAUSTIC, CAUSTIC_DIFFUSE, DIRECT, INDIRECT, SEGMENT_KINDS

LOBES = LOBE_NAMES


# Photons.usable of at least this many photons reads their count classes.
USABLE_BY_CLASS = 4096


@dataclass
class Photons:
    # power, direction and normal are float32 in a shot; with photonlayout.COMPACT on
    # (the default) a PhotonMap holds them in the compact layout (engine/photonlayout.py:
    # power (N,4) uint8 RGBE, direction and normal (N,2) int16 octahedral; its powers /
    # vectors / has_power read rows of either layout).
    position: np.ndarray   # (N,3) float32, re-centred world space
    power: np.ndarray      # (N,3) float32 watts
    direction: np.ndarray  # (N,3) float32 travel direction when it arrived
    normal: np.ndarray     # (N,3) float32 surface normal on the side it arrived from
    kind: np.ndarray       # (N,) uint8 DIRECT / CAUSTIC / INDIRECT
    emitted: int = 0       # photons emitted to produce these (for statistics)
    # (N,4) uint8 bounce counts of the path that brought each photon (photonkernels.B_TOTAL
    # ...: total, then diffuse, glossy, transmission after the first scatter; saturated at
    # 255), for the bounce limits (photonkernels.bounce_usable); None: not counted (no
    # limit applies)
    bounces: np.ndarray | None = None
    # (N,) int32 the surface each photon lies on: the object_id (Geometry.object_id, the
    # instance's own for an instance) of the triangle it was stored on. The estimates
    # accept only the query's own surface's photons, and another's where it lies in the
    # query's tangent plane (engine/samesurface.py). None: unknown (any surface's photon
    # passes, the normal test alone decides).
    surface: np.ndarray | None = None
    # (N,) float32 Filter Glossy's reverse pdf of each photon's path (1/sr; inf: none):
    # the minimum, over its non-diffuse scatters S_2 .. S_m since the light or its last
    # diffuse bounce, of the camera side's one-sample MIS pdf of the direction back
    # towards the light (photonkernels.reverse_pdf; engine/glossysplit.py reads it).
    # None: not kept (every photon inf).
    blur_pdf: np.ndarray | None = None
    # (N,) float32 |L|_1 of each photon: the radiance a Cycles path reversed along it
    # carries (Le x its chain's throughput, W sr^-1 m^-2, summed over RGB; 0: none, a
    # delta light's), for Clamp Indirect on the estimates (engine/photonclamp.py).
    # None: not kept (no clamp).
    radiance: np.ndarray | None = None

    @classmethod
    def empty(cls):
        z = np.zeros((0, 3), np.float32)
        return cls(z, z.copy(), z.copy(), z.copy(), np.zeros(0, np.uint8),
                   bounces=np.zeros((0, 4), np.uint8), surface=np.zeros(0, np.int32),
                   blur_pdf=np.zeros(0, np.float32))

    def __len__(self):
        return len(self.position)

    def select(self, mask) -> "Photons":
        """The photons where mask (N,) bool is set, or at the rows mask (K,) int."""
        rows = np.flatnonzero(mask) if np.asarray(mask).dtype == np.bool_ else mask
        return self.take(rows)

    def take(self, rows) -> "Photons":
        """The photons at rows (K,) int, in that order (np.take: a few times faster than
        fancy indexing for (N,3) rows)."""
        return Photons(*(np.take(a, rows, axis=0) for a in (
            self.position, self.power, self.direction, self.normal, self.kind)), self.emitted,
            None if self.bounces is None else np.take(self.bounces, rows, axis=0),
            None if self.surface is None else np.take(self.surface, rows),
            None if self.blur_pdf is None else np.take(self.blur_pdf, rows),
            None if self.radiance is None else np.take(self.radiance, rows))

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.position, self.power, self.direction,
                                      self.normal, self.kind)) + \
            (0 if self.bounces is None else self.bounces.nbytes) + \
            (0 if self.surface is None else self.surface.nbytes) + \
            (0 if self.blur_pdf is None else self.blur_pdf.nbytes) + \
            (0 if self.radiance is None else self.radiance.nbytes)

    def usable(self, limits, camera=(0, 0, 0, 0)) -> np.ndarray:
        """(N,) bool: the photons whose light read at a camera-side vertex reached with
        `camera` bounces (total, diffuse, glossy, transmission) stays within the bounce
        limits (4,) (RenderSettings.bounce_limits); every photon without counts."""
        if self.bounces is None:
            return np.ones(len(self), bool)
        if len(self) < USABLE_BY_CLASS:
            return pk.bounce_usable(self.bounces, limits, camera)
        # By the photons' distinct count rows (count_classes), the same bits: a map
        # build asks ~10 counts of a whole shot (bounce_usable over Figure 6's 0.7 M
        # photons: 23 ms a call, docs/performance.md mem45).
        rows, which = self.count_classes()
        return np.take(pk.bounce_usable(rows, limits, camera), which)

    def count_classes(self) -> tuple:
        """(rows (U,4) int64, which (N,) uint): the distinct rows of self.bounces and each
        photon's index into them (chaincounts.unique_counts), made on first use and kept
        while self.bounces is the same array (an array written in place after that is
        not seen: bounces are written once, by the photon pass)."""
        from .chaincounts import unique_counts
        got = self.__dict__.get("_classes")
        if got is None or got[0] is not self.bounces:
            rows, which = unique_counts(self.bounces)
            got = self.__dict__["_classes"] = (
                self.bounces, rows, which.astype(np.min_scalar_type(max(len(rows) - 1, 0))))
        return got[1], got[2]

    def __getstate__(self):
        state = dict(self.__dict__)
        state.pop("_classes", None)  # (made again where needed)
        return state


def bent_arrival(n_smooth, ns, ng, wi) -> np.ndarray:
    """(N,) the factor on a photon's power where it arrives at a hit whose normal a Normal
    Map / Bump node bent (stored for the diffuse lobe, and carried by its diffuse bounce):
    Cycles' bump shadowing term (normalmap.bump_shadowing) times |wi.ns| / |wi.ng|.
    n_smooth, ns, ng (N,3): the smooth, shading (bent) and geometric normals on the
    arriving side; wi (N,3) unit directions back towards where the photon came from.
    Why the cosine ratio: photons arrive by the surface's true area, so their density
    is the irradiance about ng, integral L |wi.ng|, while the camera side (and Cycles)
    lights the diffuse lobe by integral L |wi.ns| (Veach 1997, sec. 5.3, the adjoint
    BSDF with shading normals; engine/photonkernels.py applies it to the glossy lobes'
    reflections). Without it a normal map's patches turned away from the light read
    1.13x Cycles where their light came from photons (docs/accuracy.md, nmap37). The
    diffuse bounce needs no outgoing |wo.ng| / |wo.ns| beside it: over the cosine
    lobe about ns cut off below ng both leave the same power (the lune is symmetric in
    ns and ng). Rows whose normal is not bent (ns equal to n_smooth) keep 1."""
    out = bump_shadowing(n_smooth, ns, wi)
    bent = np.any(n_smooth != ns, axis=1)
    if bent.any():
        cs = np.maximum(np.einsum("ij,ij->i", wi[bent], ns[bent]), 0.0)
        cg = np.einsum("ij,ij->i", wi[bent], ng[bent])
        out[bent] *= np.where(cg > 0.0, cs / np.maximum(cg, 1e-300), 0.0)
    return out


def concat_surfaces(*parts: Photons) -> np.ndarray | None:
    """The parts' Photons.surface concatenated in order, or None where a part has none
    (a map of photons with and without surfaces: none is known)."""
    if any(p.surface is None for p in parts):
        return None
    return np.concatenate([p.surface for p in parts])


def _concat_optional(parts, field: str, fill: float) -> np.ndarray | None:
    """The parts' optional float32 per-photon field `field` concatenated in order (a
    part without: `fill`), or None where no part with photons has it (Photons.empty()'s
    zero-length array alone must not give every photon of the others 4 B: photon_bytes)."""
    if all(getattr(p, field) is None or len(p) == 0 for p in parts):
        return None
    return np.concatenate([np.full(len(p), fill, np.float32) if getattr(p, field) is None
                           else getattr(p, field) for p in parts])


def concat_blur_pdfs(*parts: Photons) -> np.ndarray | None:
    """The parts' Photons.blur_pdf concatenated in order (a part without: inf, no
    reverse pdf), or None where no part with photons has them."""
    return _concat_optional(parts, "blur_pdf", np.inf)


def concat_radiances(*parts: Photons) -> np.ndarray | None:
    """The parts' Photons.radiance concatenated in order (a part without: 0, no clamp),
    or None where no part keeps them."""
    return _concat_optional(parts, "radiance", 0.0)


def _store_maker(settings):
    """The stored-photon buffers' maker: photonkernels.store_arrays_radiance where the
    photon pass keeps each photon's |L|_1 (photonclamp.keeps_radiance), else
    store_arrays."""
    return (pk.store_arrays_radiance if photonclamp.keeps_radiance(settings)
            else pk.store_arrays)


def _clamp_ratios(m: int):
    """A continued-ray set's Clamp Indirect ratios (photonkernels._scatter's nx_clamp)
    for m rays, as a one-array set for _Buffers."""
    return (np.empty(m),)


def _ray_state(m: int):
    """A continued-ray set's per-ray state (photonkernels._scatter's nx_row, nx_blur) for
    m rays, as a set for _Buffers."""
    return (np.empty(m, np.int64), np.empty(m))


def trace_photons(ctx, lights, counts, caustic_only: bool, stream: int, progress=None,
                  should_cancel=None, targets=None, first_hit=None, label=None) -> Photons:
    """Emit counts[i] photons from lights[i] and trace them. caustic_only: keep L S+ D
    paths only and stop a photon as soon as it scatters diffusely (the caustic shot).
    targets=(centers, radii): aim the photons at these bounding spheres (caustic casters:
    one or several per caster, engine/casterspheres.py).
    first_hit=(is_caster, keep): is_caster (objects,) bool by object id; store CAUSTIC
    photons only if whether the first surface they hit belongs to a caster equals keep.
    An aimed shot (keep=True) and an unaimed one (keep=False) thus split the L S+ D paths
    between them without overlap: a path whose first hit is a caster starts inside one of
    that caster's spheres, which the aimed shot covers (engine/render.py).
    label: what the progress text calls the photons ("Tracing {label} 62k/400k");
    default "caustic photons" for a caustic_only shot, else "photons"."""
    settings = ctx.settings
    total = int(sum(counts))
    jobs = []
    # Many lights with few photons each emit in groups (engine/lights/group.py).
    for li, emitter, count in photon_emitters(lights, counts, settings.chunk_size):
        chunk = chunk_length(count, settings.chunk_size)  # same for any thread count
        jobs += [(li, ci, start, min(chunk, count - start), count, emitter, None)
                 for ci, start in enumerate(range(0, count, chunk))]
        # Shadow Linking: the light's photons again, those that pass a non-blocker first
        # continuing from the blocker behind it (lightlinking.blocker_accel_of).
        past = blocker_accel_of(ctx, emitter)
        if past is not None:
            jobs += [(li, ci, start, min(chunk, count - start), count, emitter, past)
                     for ci, start in enumerate(range(0, count, chunk))]
    threads = settings.threads
    accel = ctx.accel.serial() if threads > 1 and len(jobs) > 1 else ctx.accel
    pool = _Buffers()
    # On one thread the chunks run one after another, in order (parallel.ordered_map:
    # one in flight), so each stores straight into the shot's arrays after the chunks
    # before it (no copy per chunk); on more, chunks finish out of order and are copied
    # in order (_Shot.append).
    shot = _Shot(total, direct=threads <= 1, make=_store_maker(settings))
    plain = pk.lobe_classes(ctx.table.closure_params)  # once a trace, not a chunk

    def job(item, stop):
        li, ci, start, n, count, emitter, past = item
        # (a chunk's second run past non-blockers: the same numbers, the same photons)
        rng = np.random.default_rng([settings.seed, stream, li, ci])
        if shot.direct:
            shot.begin(n)
        stored = _trace_chunk(ctx, accel, emitter, n, count, rng, caustic_only, targets,
                              stop, first_hit, pool, shot if shot.direct else None, plain,
                              link_row=link_row_of(ctx, emitter),
                              mesh_links=mesh_photon_links(ctx, emitter), past=past)
        if shot.direct:
            # here, on the chunk's thread, before the next starts
            shot.commit(stored, n if past is None else 0)
        return stored

    done = 0
    for item, stored in zip(jobs, ordered_map(job, jobs, threads, should_cancel)):
        done += item[3] if item[6] is None else 0
        shot.append(stored, done)
        stored.release()
        if progress is not None:
            if label is None:
                label = "caustic photons" if caustic_only else "photons"
            progress("photons", done / max(total, 1), f"Tracing {label} {short_count(done)}/{short_count(total)}")
    out = shot.photons()
    out.emitted = total
    if not settings_filter_glossy(settings) > 0.0:
        out.blur_pdf = None  # (no state kept: every photon's inf; 4 B a photon not held)
    return out


def _trace_chunk(ctx, accel, light, n, count, rng, caustic_only, targets, should_cancel,
                 first_hit=None, pool=None, shot=None, plain=None, link_row=None,
                 mesh_links=None, past=None):
    """Emit n of the light's `count` photons and trace them; returns the stored hits (a
    _Stored). Between two Embree calls the work is one compiled kernel
    (photonkernels.scatter, which computes the surface data itself); bsdf.surface_hit
    supplies the surface data instead where a material has a texture, normal map or alpha
    texture, and photonkernels.photon_surfaces with shared instances. pool: the
    trace's _Buffers, which lends the stored-photon and continued-ray buffers (a new
    one without). shot: a direct _Shot the photons are stored into after its rows (the
    caller commits them), or None: into blocks from the pool. plain: the table's
    photonkernels.lobe_classes (computed here without). link_row (M,) bool: the objects
    the light lights (Light Linking, lightlinking.link_row_of; None: every one);
    mesh_links: (LightLinks, the mesh light) when emitting meshes have links of their own
    (lightlinking.mesh_photon_links; each photon's by its triangle), else None. past:
    Shadow Linking's blocker BVH of the light (lightlinking.BlockerAccel): only the
    photons whose first hit is not one of its blockers are kept, continuing from the
    blocker behind (lightlinking.past_non_blockers); None: an ordinary chunk."""
    geo, table, settings = ctx.geo, ctx.table, ctx.settings
    pool = pool if pool is not None else _Buffers()
    # Each photon keeps its slot in the chunk, and its random numbers are those of its
    # slot (photonkernels.uniform), emission included: a photon whose path changes (a hit
    # a hair from an edge, rounded differently in a scaled scene) does not change the
    # paths of others. The light's kernel writes the rays of the photons that carry power
    # (engine/lights/emission.py).
    key = emission_key(rng)
    # The emitted rays go straight into a continued-ray set of the pool (fresh arrays
    # per chunk cost page faults), with the path flags and ray kinds of its columns; the
    # set becomes the second bounce's output (nxt_sets[1]) once bounce 0 has read it.
    # Surfaces touching glass (engine/coincident.py; None: no glass touches anything):
    # with them the continued rays keep the triangle they left and their offset.
    coincident = CoincidentSurfaces.for_context(ctx)
    make_next = pk.next_arrays if coincident is None else pk.next_arrays_from
    first = pool.take(make_next, n)
    out = EmissionBuffers(n, (first[0], first[1], first[2], first[3], first[6]))
    nxt_sets = [None, first]
    if targets is None:
        m = light.emit_into(key, 0, n, count, out, 0)
    else:
        m = light.emit_towards_into(key, 0, n, count, targets, out, 0)
    o, d32, d, power, flags, kinds, slot, bnc, frm, off = (a[:m] for a in first)
    flags[:] = 0
    bnc[:] = 0  # no bounce yet
    frm[:] = -1  # from a light, not a triangle
    # Ray visibility (docs/scene_format.md, "Ray visibility"). A segment arriving at a
    # surface stands for the camera-side ray that leaves that surface backwards; `kinds`
    # holds, per photon, the ray kinds for which the segment so far is a valid camera-side
    # ray (photonkernels.scatter applies the rules). The first segment also needs the
    # light to be visible to the kind it stands for (Light.ray_kinds).
    light_kinds = int(light.ray_kinds) & SEGMENT_KINDS
    vis_on = bool(getattr(accel, "has_invisible", False)) or light_kinds != SEGMENT_KINDS
    kinds[:] = light_kinds
    if first_hit is None:
        caster, mode = np.zeros(1, np.bool_), 0
    else:
        caster, mode = np.ascontiguousarray(first_hit[0], np.bool_), 2 if first_hit[1] else 1
    numpy_hits = _needs_numpy_hits(table)
    # Surface data as arrays only where the scatter kernel cannot compute it itself: the
    # numpy texture evaluation, and shared instances (their offsets take a floor computed
    # from the points, Geometry.instance_offset_floor).
    given = numpy_hits or geo.shared is not None
    if plain is None:
        plain = pk.lobe_classes(table.closure_params)
    # Buffers for the whole chunk, reused bounce after bounce: the surface data (given
    # only), the stored photons (appended to by each bounce), and two sets of continued
    # rays (one is the bounce's input, the other its output).
    surf = pk.surface_arrays(m if given else 0)
    factors = pool.take(_factors, m)
    bump, tfar, hit_rows, hits = _factor_views(factors, m)
    stored = _Stored(2 * m + 1024, pool, shot, _store_maker(settings))
    # Clamp Indirect (engine/photonclamp.py): each photon's |Le|_1 / |power|_1.
    clamp0 = (photonclamp.emission_ratios(light, o, d, power, slot, key)
              if photonclamp.keeps_radiance(settings) else None)
    # A sun's or the world's photons refracted through a next-event pane stay direct
    # (engine/panelight.py), and a lamp's through its Translucent BSDF or rough glass
    # shade (engine/shadelight.py).
    pane_tri = next_event_tri(ctx, light)
    # A light no shadow ray samples (its diffuse visibility off) crosses window glass as
    # a caustic: its photons keep the path they take there (passages_carried).
    flat = pk.flat_tables(geo, table) if passages_carried(light) else _NO_PASSAGES
    try:
        _bounces(ctx, accel, settings, geo, table, key, o, d32, d, power, slot, flags, kinds,
                 bnc, frm, off, vis_on, caster, mode, numpy_hits, given, plain, surf, bump,
                 tfar, hit_rows, hits, stored, nxt_sets, pool, caustic_only, should_cancel,
                 coincident, make_next, pane_tri, soft_falloff_sources(light, n),
                 start_medium=_light_medium(ctx, light), link_row=link_row,
                 mesh_links=mesh_links, past=past, flat=flat, clamp0=clamp0,
                 clamp_light=light)
    except BaseException:
        stored.release()
        raise
    finally:
        for arrays in nxt_sets:
            if arrays is not None:
                pool.give(arrays, make_next)
        pool.give(factors, _factors)
    return stored


_NO_PASSAGES = (pk._NO_FLAT_MAT, pk._NO_FLAT_LIMIT)  # (flat_tables' "none")
# Photons out of a flat passage keep blurredpassage's factor at Filter Glossy > 0 (with
# blurredpassage.CYCLES_BLUR; False: the shadow rays' side alone).
BLUR_PASSAGE_PHOTONS = True
# Photons past a diffuse bounce scatter off lobes blurred by Filter Glossy
# (photonkernels._scatter's gather_fg; docs/accuracy.md "photonblur49"). False: unblurred.
BLUR_GATHER_PHOTONS = True
# ... and a photon without a diffuse bounce is split at its first non-diffuse scatter into
# an unblurred copy for the caustic map and a blurred one for the others
# (photonkernels._scatter's split_slots; docs/accuracy.md "photonblur50", "split50").
# False: that scatter stays unblurred for both. On: the glossy box reads 1.003-1.009 of
# Cycles (1.010-1.022 off), the bathroom 1.006 (1.021); the sharp floor's Filter Glossy
# ratio moves 0.4-0.8 % down, well inside its seed spread (split50).
SPLIT_GATHER_PHOTONS = True


def passages_carried(light) -> bool:
    """Whether the photons of light (a Light or a lights.group.LightGroup, whose members
    share their ray visibility) leave a flat passage as the path they entered it
    (photonkernels.scatter; docs/design.md, Transparent shadows): only where the camera's
    shadow rays carry that light through the window, i.e. they sample it (its diffuse
    visibility on). A light whose shadow rays are off (integrator.MODE_CONTINUATION)
    reaches a floor under window glass as Cycles finds it, by the path's refraction:
    its photons through the glass stay caustic, read at the floor from the caustic map
    (issue 14, docs/compatibility.md "passages48": a diffuse-invisible area light over a
    1 cm slab read 0.025 for Cycles' 1.168). An emissive mesh keeps its passages: the
    sides no shadow ray samples reach the floor by the gather rays that cross the glass
    (engine/gatherpassages.py)."""
    return bool(int(light.ray_kinds) & SHADOW)


def _light_medium(ctx, light) -> int:
    """The medium (a material row) a point, spot or area light's position is in
    (engine/mediumstart.py), -1: none, or another kind of light."""
    # (outside every object's medium: the world volume's row, engine/worldmedium.py)
    world_row = worldmedium.medium_row(ctx)
    if getattr(light, "kind", None) not in (POINT, SPOT, AREA) or not hasattr(light, "pos"):
        return world_row
    sigma = media.absorption_table(ctx.table)
    if not sigma.shape[0]:
        return -1
    return point_medium(ctx, np.asarray(light.pos, np.float64), sigma, outside=world_row)


def _bounces(ctx, accel, settings, geo, table, key, o, d32, d, power, slot, flags, kinds,
             bnc, frm, off, vis_on, caster, mode, numpy_hits, given, plain, surf, bump, tfar,
             hit_rows, hits, stored, nxt_sets, pool, caustic_only, should_cancel, coincident,
             make_next, pane_tri=None, soft=None, start_medium=-1, link_row=None,
             mesh_links=None, past=None, flat=None, clamp0=None, clamp_light=None):
    """_trace_chunk's bounces: one Embree call and one scatter call each, until no photon
    is left or max_photon_depth; the stored photons go to `stored`, the continued rays
    alternate between the two buffer sets of nxt_sets (borrowed from pool, made by
    make_next); coincident: the scene's CoincidentSurfaces or None; pane_tri: the
    next-event panes' triangle table for this light's photons (panelight.Panes.photon_tri)
    or None; soft: soft_falloff_sources' (centre, r^2, ends) per light, or None;
    start_medium: the medium the light is in (_light_medium; -1: none known); link_row,
    mesh_links, past: _trace_chunk's; flat: the flat-passage tables its photons cross
    (photonkernels.flat_tables; None: the scene's); clamp0: photonclamp.emission_ratios'
    (M,) (a ratio per emitted ray) or None (no Clamp Indirect radiance kept);
    clamp_light: with clamp0, the photons' light, whose next-event pdf at each photon's
    first scatter that scatter's ratio takes (photonclamp.light_pdfs; None: not taken)."""
    # Flat passages through thin glass (docs/design.md, Transparent shadows).
    if flat is None:
        flat = pk.flat_tables(geo, table)
    aniso_tan = triangle_tangents(geo, table.closure_params)
    # Filter Glossy's split of pre-diffuse photons (photonkernels._scatter's split_slots):
    # the blurred copies take the slots after the chunk's own (their own random
    # numbers); 0: no split.
    fg = float(getattr(settings, "cycles_filter_glossy", 0.0) or 0.0)
    n_slots = int(slot.max()) + 1 if len(slot) else 0
    split_slots = (n_slots if BLUR_GATHER_PHOTONS and SPLIT_GATHER_PHOTONS and fg > 0.0
                   and not caustic_only else 0)
    # The paths' state is kept per ray, not per slot (a copy passing behind a surface
    # shares its photon's slot and random numbers, not its path): the scatter writes each
    # continued ray's row of the bounce's rays (nx_row), from which the media, the volume
    # scatters and the touching-glass record of the next bounce are taken (and the
    # Filter Glossy state, nx_blur, as nx_clamp: docs/accuracy.md "slots56").
    # Absorbing media inside objects (engine/media.py): each ray's medium (None: no
    # absorbing material, nothing done); a lamp inside a fog cube: its photons start in it.
    sigma = media.absorption_table(table)
    pmed = media.PhotonMedia(sigma, len(o), max(start_medium, -1)) if sigma.shape[0] else None
    world_row = worldmedium.medium_row(ctx)
    # Scattering media (engine/photonmedium.py; None: no photon scatters in a medium).
    vol = (photonmedium.PhotonScattering.for_chunk(table, settings, len(o), caustic_only)
           if pmed is not None else None)
    het = getattr(ctx, "hetero", None)
    if het is None or not het.fields or pmed is None:
        het = None
    elif vol is not None:
        vol.hetero = het  # (the free flights' scatter weights)
    limits = settings.bounce_limits
    # Cycles' Filter Glossy on the maps' paths (engine/glossysplit.py): each ray's
    # reverse-pdf state (photonkernels._scatter's blur / nx_blur; -1: none yet).
    blur = (np.full(len(o), -1.0)
            if settings_filter_glossy(settings) > 0.0 else pk.NO_BLUR_STATE)
    # The scatter's nx_row and nx_blur, one set per buffer set (as nxt_sets); nx_row only
    # where some per-ray state is kept here.
    rows_on = pmed is not None or coincident is not None
    state_sets = [None, None]
    # Clamp Indirect's |L|_1 / |power|_1 per ray (not per slot: a copy passing behind
    # a surface shares its photon's slot, not its path); the scatter writes the
    # continued rays' into the set of the bounce's output (clamp_sets[k], as nxt_sets).
    clamp = pk.NO_CLAMP if clamp0 is None else np.ascontiguousarray(clamp0, np.float64)
    clamp_sets = [None, None]
    # Cycles' blurred window glass (engine/blurredpassage.py): photons out of a flat
    # passage keep its factor (None: off, Filter Glossy 0, or no passage crossed).
    passage_blur = ((fg, blurredpassage.table(), blurredpassage.IOR)
                    if blurredpassage.CYCLES_BLUR and BLUR_PASSAGE_PHOTONS and fg > 0.0
                    and len(flat[0]) else None)
    # Which rays' last hit was a touching glass face met from inside
    # (CoincidentSurfaces.meet_hits; None: no glass touches anything).
    arrived = np.zeros(len(o), bool) if coincident is not None else None
    for bounce in range(settings.max_photon_depth):
        if should_cancel is not None and should_cancel():
            raise Cancelled()
        m = len(o)
        if m == 0:
            break
        if m > len(bump):
            surf = pk.surface_arrays(m if given else 0)
            bump, tfar, hit_rows, hits = _factor_views(_factors(m), m)
        tfar[:m] = _UNBOUNDED
        # Embree's own answer: int32 ids, float32 barycentrics; scatter reads them as they
        # are (Accel.intersect_hits).
        geom, prim32, u, v, starts = _closest_hits(accel, o, d32, tfar[:m],
                                                   tuple(a[:m] for a in hits))
        if bounce == 0 and past is not None:
            # Shadow Linking's second run: the photons that passed a non-blocker first,
            # at the blocker behind it (the others end).
            starts = past_non_blockers(past, o, d32, geom, prim32, u, v, tfar[:m], starts)
        if bounce == 0 and soft is not None:
            _soft_falloff_at_first_hit(soft, o, d, tfar[:m], geom, slot, power)
        if coincident is not None:
            # Photons leaving a glass face another surface touches (refracted out
            # through a bottle's cap onto the floor), or that surface into the glass,
            # meet the other one there; photons inside the glass reaching the floor
            # under it leave the glass first (engine/coincident.py).
            coincident.meet_hits(o, d, frm, off, geom, prim32, u, v, tfar[:m], starts,
                                 arrived)
        if bounce == 0 and link_row is not None:
            # Light Linking: a photon whose first hit is on an object its light does not
            # light ends there, as a miss (not stored, not bounced; engine/lightlinking.py).
            unlinked_first_hits(ctx.geo, link_row, geom, prim32, starts)
        elif bounce == 0 and mesh_links is not None:
            # ... and for the emitting meshes with links of their own, by the triangle
            # each photon left.
            links, mesh_light = mesh_links
            unlinked_first_hits(ctx.geo, None, geom, prim32, starts,
                                mesh_photon_rows(links, mesh_light, key, slot), links.emit_lit)
        if given:
            # Triangle rows and float64 barycentrics for numpy and instance paths (the
            # same values as Accel.intersect's).
            prim = np.where(geom >= 0, np.take(starts, np.maximum(geom, 0)) + prim32, -1)
            u64, v64 = u.astype(np.float64), v.astype(np.float64)
        else:
            prim = _NO_HITS
        surf_m = tuple(a[:m] for a in surf)
        params, row_plain, mat_ior = table.closure_params, plain, table.ior
        may_diffuse = _NO_MAY_DIFFUSE
        if numpy_hits:
            bump[:m] = 1.0
            rows = np.nonzero(prim >= 0)[0]
            hit = surface_hit(geo, table, prim[rows], u64[rows], v64[rows], d[rows])
            alpha = (np.take(table.alpha, hit.mat) if hit.alpha is None else hit.alpha)
            for dst, src in zip(surf_m, (hit.p, hit.ng, hit.ns, hit.front, hit.mat, hit.base,
                                         alpha, hit.offset)):
                dst[rows] = src
            if hit.n_smooth is not None:
                # Bent normals (Normal Map / Bump): the diffuse lobe takes Cycles' bump
                # shadowing term for the arriving direction, stored and bounced alike,
                # and the adjoint's |wi.Ns| / |wi.Ng| (bent_arrival).
                bump[rows] = bent_arrival(hit.n_smooth, hit.ns, hit.ng, -d[rows])
            if hit.params is not None:
                # Texture-driven scalar inputs: the scatter kernel reads one parameter row
                # per photon (its "material" index is its own row).
                params = np.zeros((m, table.closure_params.shape[1]))
                params[rows] = hit.params
                surf_m[4][:] = np.arange(m)
                mat_ior = np.ascontiguousarray(params[:, M_IOR])
                row_plain = pk.lobe_classes(params)
                # Stored wherever the material may have a diffuse lobe, not only where
                # this hit's values (a Mix Shader's closure pick, a metallic map) give it
                # one: the camera hit weighs the density by its own diffuse weight. Not
                # where the surface is not there (alpha 0), as before.
                may_diffuse = np.zeros(m, np.bool_)
                may_diffuse[rows] = np.take(table.has_diffuse, hit.mat) & (alpha > 0)
        # Shared instances: the hits' rows gathered (geometry.Geometry.hit_tables).
        rows, (v0, e1, e2, normals, material, visibility, object_id) = geo.hit_tables(
            prim, "v0", "e1", "e2", "corner_normals", "material", "visibility", "object_id")
        if geo.shared is not None:
            # scatter reads the gathered rows: hit i is on row i (-1: a miss).
            geom, prim32, starts = rows_as_hits(rows)
        scattered = None
        if vol is not None:
            # Free flights in scattering media: the photons that scatter before their
            # surface go on from the medium point (after the surface scatter's own).
            scattered = vol.flights(key, bounce, o, d, tfar[:m], geom, power, slot, bnc,
                                    pmed.medium, clamp)
        if pmed is not None:
            # A photon that travelled inside an absorbing object's medium keeps
            # exp(-sigma_a s) of its power over the segment (Beer-Lambert), before the
            # scatter stores or continues it.
            pmed.attenuate(geom, prim32, starts, material, e1, e2, d, tfar[:m], power)
            if het is not None:
                # Density textures (engine/heterogeneous.py): the mean density's
                # stand-in times the ratio-tracked correction over the segment (the
                # photons that scattered on it, a miss now, take theirs in flights).
                power *= het.correction(o, d, np.where(np.asarray(geom) >= 0, tfar[:m], 0.0),
                                        salt=5)
        if given and not numpy_hits:
            pk.photon_surfaces(rows, u64, v64, d, v0, e1, e2, normals, material,
                               table.base_color, table.alpha, *surf_m)
            floor = geo.instance_offset_floor(prim, surf_m[0], surf_m[1])
            if floor is not None:  # shared instances: object-space rounding (Geometry)
                np.maximum(surf_m[7], floor, out=surf_m[7])
        need = m * (1 + bool(vis_on) + bool(split_slots))
        k = bounce % 2
        if nxt_sets[k] is None or len(nxt_sets[k][0]) < need:
            if nxt_sets[k] is not None:
                pool.give(nxt_sets[k], make_next)
            nxt_sets[k] = None
            nxt_sets[k] = pool.take(make_next, need)
        nx_clamp = pk.NO_CLAMP
        if clamp0 is not None:
            if clamp_sets[k] is None or len(clamp_sets[k][0]) < need:
                if clamp_sets[k] is not None:
                    pool.give(clamp_sets[k], _clamp_ratios)
                clamp_sets[k] = None
                clamp_sets[k] = pool.take(_clamp_ratios, need)
            nx_clamp = clamp_sets[k][0]
        nx_row, nx_blur = pk.NO_ROWS, pk.NO_BLUR_STATE
        if rows_on or len(blur):
            if state_sets[k] is None or len(state_sets[k][0]) < need:
                if state_sets[k] is not None:
                    pool.give(state_sets[k], _ray_state)
                state_sets[k] = None
                state_sets[k] = pool.take(_ray_state, need)
            if rows_on:
                nx_row = state_sets[k][0]
            if len(blur):
                nx_blur = state_sets[k][1]
        light_pdf = pk.NO_CLAMP
        if clamp0 is not None and clamp_light is not None and photonclamp.NEE_FIRST_SCATTER:
            # Cycles' light sample beside its BSDF sample at the light's first scatter
            # (photonclamp, "The light's first scatter").
            light_pdf = _first_scatter_light_pdfs(ctx, clamp_light, o, d, tfar[:m], geom,
                                                  prim32, starts, bnc, slot, e1, e2)
        n_st, n_nx = pk.scatter(key, bounce, d, power, flags, kinds, slot, bnc, geom, prim32,
                                starts, u, v, v0, e1, e2, normals, material, table.base_color,
                                table.alpha, given, *surf_m, bump[:m] if numpy_hits else _NO_BUMP,
                                params, row_plain, mat_ior,
                                visibility, object_id, caster, mode, bool(caustic_only),
                                vis_on, limits, *stored.room(m), *nxt_sets[k], hit_rows,
                                flat_mat=flat[0], flat_limit=flat[1], aniso_tan=aniso_tan,
                                may_diffuse=may_diffuse, blur=blur,
                                passage_blur=passage_blur,
                                gather_blur=fg if BLUR_GATHER_PHOTONS else 0.0,
                                split_slots=split_slots, clamp=clamp, nx_clamp=nx_clamp,
                                nx_blur=nx_blur, nx_row=nx_row,
                                light_pdf=light_pdf,
                                # (no shadow ray crosses a transparent pass - Transparent
                                # bounces 0, or none in the scene: a pass after a pane
                                # makes its photon caustic, the pane's rays stop there)
                                pane_passes=getattr(ctx, "shadow", None) is not None,
                                **({} if pane_tri is None else {"pane_tri": pane_tri}))
        stored.count += n_st
        if scattered is not None:
            # (a medium's scatter is a diffuse bounce to the reverse pdfs' state: -1)
            n_nx = photonmedium.continue_scattered(nxt_sets[k], n_nx, scattered, flags, kinds,
                                                   bnc, slot, clamp, nx_clamp, nx_row, nx_blur)
        o, d32, d, power, flags, kinds, slot, bnc, frm, off = (a[:n_nx] for a in nxt_sets[k])
        if len(nx_clamp):
            clamp = nx_clamp[:n_nx]
        if len(blur):
            blur = nx_blur[:n_nx]
        parent = nx_row[:n_nx]
        if pmed is not None:
            # refracted in or out of a medium; out of an object's medium into the world
            # volume's, if any (worldmedium.py)
            pmed.after_scatter(parent, d, outside=world_row)
        if vol is not None:
            vol.count = vol.count[parent]
        if arrived is not None:
            arrived = arrived[parent]
    for arrays in clamp_sets:
        if arrays is not None:
            pool.give(arrays, _clamp_ratios)
    for arrays in state_sets:
        if arrays is not None:
            pool.give(arrays, _ray_state)


def _first_scatter_light_pdfs(ctx, light, o, d, t, geom, prim, starts, bnc, slot, e1, e2):
    """(m,) float64: photonclamp.light_pdfs at the hits of the photons that have not
    scattered yet (no bounce counted; 0 elsewhere and for misses), for the scatter's
    light_pdf: o, d (m,3) the rays, t (m,) their hit distances, geom, prim, starts the
    hits (as the scatter reads them: triangle row starts[geom] + prim of e1, e2), bnc
    (m,) packed bounce counts, slot (m,) (a LightGroup's member by slot). The hit's
    geometric normal, turned towards the light, stands for its normal."""
    m = len(d)
    out = np.zeros(m)
    g = np.asarray(geom)[:m]
    t = np.asarray(t[:m], np.float64)
    rows = np.flatnonzero((g >= 0) & ((np.asarray(bnc)[:m] & pk._B_MASK) == 0)
                          & np.isfinite(t))
    if not len(rows):
        return out
    tri = np.asarray(starts, np.int64)[g[rows]] + np.asarray(prim)[rows]
    ng = np.cross(np.asarray(e1)[tri], np.asarray(e2)[tri]).astype(np.float64)
    ng /= np.maximum(np.linalg.norm(ng, axis=1), 1e-300)[:, None]
    wi = -np.asarray(d, np.float64)[rows]
    ng *= np.where(np.einsum("ij,ij->i", ng, wi) < 0.0, -1.0, 1.0)[:, None]
    x = np.asarray(o, np.float64)[rows] + t[rows, None] * -wi
    out[rows] = photonclamp.light_pdfs(ctx, light, x, wi, ng, np.asarray(slot)[rows])
    return out



class _Buffers:
    """Buffers lent to a trace's chunks and given back when a chunk is done with them (its
    continued-ray sets when it ends, its stored-photon blocks once the shot has copied
    them), so later chunks reuse memory that is already mapped instead of faulting in
    fresh pages (on a cold process a third of the photon pass went to the kernel's page
    faults). Every lent row is written before it is read, so the photons do not depend
    on what a buffer held before. Shared by the trace's threads (a lock); dropped with
    the trace."""

    def __init__(self):
        self._free = []
        self._lock = threading.Lock()

    def take(self, make, rows: int):
        """A set of arrays from make(rows) (pk.store_arrays, pk.next_arrays, _factors)
        with at least `rows` rows: the smallest free one that fits, else a new one."""
        with self._lock:
            fits = [i for i, (f, arrays) in enumerate(self._free)
                    if f is make and len(arrays[0]) >= rows]
            if fits:
                best = min(fits, key=lambda i: len(self._free[i][1][0]))
                return self._free.pop(best)[1]
        return make(rows)

    def give(self, arrays, make):
        """Take back a set of arrays that make (as for take) made."""
        with self._lock:
            self._free.append((make, arrays))


class _Stored:
    """A chunk's stored photons (pk.store_arrays), appended to bounce by bounce, in blocks:
    when the current block has no room for a bounce, it is kept as it is and a new one
    started (no copy as the chunk's photons grow). Blocks come from the trace's
    _Buffers and go back to it on release(). With a direct _Shot the photons go into the
    shot's arrays after its rows instead (count: this chunk's rows there; no blocks)."""

    def __init__(self, capacity: int, pool: _Buffers | None = None, shot=None,
                 make=None):
        self.pool = pool if pool is not None else _Buffers()
        self.shot = shot
        # (pk.store_arrays, or store_arrays_radiance with Clamp Indirect's radiance)
        self.make = make if make is not None else pk.store_arrays
        self.blocks = []  # full blocks: (arrays, rows used)
        self.arrays = self.pool.take(self.make, capacity) if shot is None else ()
        self.count = 0  # rows used in the current block

    def room(self, m: int):
        """Views of the current block's rows from `count` on, at least m of them."""
        if self.shot is not None:
            return self.shot.room(self.count, m)
        if self.count + m > len(self.arrays[0]):
            self.blocks.append((self.arrays, self.count))
            self.arrays = self.pool.take(self.make, max(len(self.arrays[0]), m))
            self.count = 0
        return tuple(a[self.count:] for a in self.arrays)

    def parts(self):
        """[(arrays, rows used)] in storing order (none when stored into a shot)."""
        if self.shot is not None:
            return []
        return self.blocks + [(self.arrays, self.count)]

    @property
    def total(self) -> int:
        if self.shot is not None:
            return self.count
        return sum(n for _, n in self.parts())

    def release(self):
        """Give the blocks back to the pool (after the shot copied them)."""
        for arrays, _ in self.parts():
            self.pool.give(arrays, self.make)
        self.blocks, self.arrays, self.count = [], (), 0


class _Shot:
    """A shot's stored photons, the chunks' appended in order as they finish: one copy
    from a chunk's buffers into the shot's (no trimmed copy per chunk and concatenation),
    and a chunk's buffers (~2x its rays) go back to the trace's _Buffers once copied.
    The shot's arrays are sized from the photons stored per photon emitted so far (grown
    if that falls short, trimmed at the end if much is left over).

    direct (the trace runs its chunks one after another, in order): each chunk's scatter
    calls store straight into the shot's arrays after its rows (room), and the chunk
    commits its rows when it ends; append then copies nothing. The arrays start at
    DIRECT_ROWS rows per photon of the shot (the pages of a fresh mapping that are never
    written cost no memory; the spare is cut off in place at the end) and grow as the rate so far asks."""

    DIRECT_ROWS = 2  # stored photons per emitted photon reserved up front (direct)

    def __init__(self, total: int, direct: bool = False, make=None):
        self.total = total
        self.make = make if make is not None else pk.store_arrays  # (as _Stored's)
        self.direct = direct
        self.arrays = None
        self.count = 0
        self.emitted = 0  # photons of the chunks committed so far (direct)
        self.running = 0  # photons of the chunk storing now (direct)

    def _grow(self, need: int, used: int, emitted: int):
        """Arrays of at least `need` rows holding the first `used` rows of the current
        ones; emitted: photons emitted for the rows so far (the rate's denominator)."""
        # Expected for the whole shot at the rate so far, 5 % spare; at least 1.5x the
        # arrays it replaces (a rate that keeps rising copies a bounded number of times).
        expect = int(need * self.total / max(emitted, 1) * 1.05) + 1024
        if self.arrays is not None:
            expect = max(expect, len(self.arrays[0]) * 3 // 2)
        grown = self.make(max(need, expect) if emitted < self.total else need)
        if self.arrays is not None:
            for new, old in zip(grown, self.arrays):
                new[:used] = old[:used]
        self.arrays = grown

    def room(self, rows: int, m: int):
        """(direct) Views of the shot's arrays after its rows and the current chunk's
        first `rows`, at least m rows of them."""
        start = self.count + rows
        if self.arrays is None:
            self.arrays = self.make(max(self.DIRECT_ROWS * self.total + 1024, start + m))
        elif start + m > len(self.arrays[0]):
            self._grow(start + m, start, self.emitted + self.running)
        return tuple(a[start:] for a in self.arrays)

    def begin(self, n: int):
        """(direct) A chunk of n photons starts storing."""
        self.running = n

    def commit(self, stored: _Stored, n: int):
        """(direct) A chunk of n photons is done: its stored rows become the shot's."""
        self.count += stored.count
        self.emitted += n
        self.running = 0

    def append(self, stored: _Stored, emitted: int):
        """Add a chunk's photons; emitted: photons emitted by the chunks appended so far,
        this one included. (A chunk stored into this shot directly is there already.)"""
        if stored.shot is self:
            return
        need = self.count + stored.total
        if self.arrays is None or need > len(self.arrays[0]):
            self._grow(need, self.count, emitted)
        for arrays, rows in stored.parts():
            for dst, src in zip(self.arrays, arrays):
                dst[self.count:self.count + rows] = src[:rows]
            self.count += rows

    def photons(self) -> Photons:
        if self.arrays is None or self.count == 0:
            return Photons.empty()
        n = self.count
        if 8 * (len(self.arrays[0]) - n) > n:
            # Over 1/8 spare: a trimmed copy. (Not ndarray.resize(refcheck=False): a view
            # of the arrays still alive anywhere would then read freed memory; the copy
            # costs ~17 ms a Figure 8 render.)
            a = [x[:n].copy() for x in self.arrays]
        else:
            a = [x[:n] for x in self.arrays]
        self.arrays = None
        return Photons(*a[:5], bounces=a[5], surface=a[6], blur_pdf=a[7],
                       radiance=a[8] if self.make is pk.store_arrays_radiance else None)


def _factors(m: int):
    """Per-photon buffers for m photons: the bump shadowing factors (float64), the
    rays' tmax handed to Embree (float32, which Embree overwrites), scatter's scratch
    rows (2, m) int64, and Embree's answer: geometry and triangle ids (2, m) int32,
    barycentrics u, v (m,) float32 (Accel.intersect_hits' out)."""
    return (np.empty(m), np.empty(m, np.float32), np.empty((2, m), np.int64),
            np.empty((2, m), np.int32), np.empty(m, np.float32), np.empty(m, np.float32))


def _factor_views(factors, m: int):
    """What the bounces use of a _factors set of at least m rows: the bump factors (m,)
    (not set: read only where the bounce sets them, numpy_hits), the tmax (m,),
    scatter's scratch rows, and Embree's answer arrays (geom, prim, u, v)."""
    bump, tfar, hit_rows, ids, u, v = factors
    bump = bump[:m]
    return bump, tfar[:m], hit_rows, (ids[0], ids[1], u, v)


_UNBOUNDED = np.finfo(np.float32).max  # tmax of a photon ray (Accel.intersect's default)
_NO_HITS = np.zeros(0, np.int64)
_NO_MAY_DIFFUSE = np.zeros(0, np.bool_)  # scatter: stored where the hit's diffuse weight > 0
_NO_BUMP = np.zeros(0)  # scatter: no bent normals, every photon's bump factor is 1


def soft_falloff_sources(emitter, n):
    """(centre (L,3), r^2 (L,), ends (L,) int64) float64 per light of a photon job of n
    photons, for point and spot lights with a radius and Blender's Soft Falloff (Cycles'
    point_light_sample without is_sphere: a disk of radius r through the centre facing the
    shading point, so a point at distance d receives I / (d^2 + r^2) face-on); r^2 = 0
    for the job's other lights. Light k owns the emission slots ends[k - 1] (0 for k = 0)
    up to ends[k]. None where no light of the job has it. emitter: a light, a
    visual-importance RegionEmitter (its .light) or a LightGroup (its members' slots in
    order). One row per light, not per slot: a chunk's (n,3) table cost ~2 ms a chunk."""
    members = (list(zip(emitter.lights, emitter.counts)) if hasattr(emitter, "counts")
               and hasattr(emitter, "lights") else [(getattr(emitter, "light", emitter), n)])
    if not any(_is_soft(li) for li, _ in members):
        return None
    centre, r2 = np.zeros((len(members), 3)), np.zeros(len(members))
    ends = np.cumsum([int(c) for _, c in members], dtype=np.int64)
    for k, (li, _) in enumerate(members):
        if _is_soft(li):
            centre[k] = li.pos
            r2[k] = float(li.radius) ** 2
    return centre, r2, ends


def _is_soft(light) -> bool:
    return (getattr(light, "kind", None) in (POINT, SPOT)
            and float(getattr(light, "radius", 0.0)) > 0.0 and not light.is_sphere)


def _soft_falloff_at_first_hit(soft, o32, d, t32, geom, slot, power):
    """Photons leave the light's sphere of radius r (engine/lights/point.py), whose light
    falls as I / d^2; with Soft Falloff the camera side takes Cycles' facing disk, I / (d^2
    + r^2). So each photon's power at its first hit, at distance d from the light's
    centre, is scaled by d^2 / (d^2 + r^2): both passes then give the same irradiance
    (within a few radii of the light: a lamp shade read 1.19x Cycles without it,
    newuser31). soft: soft_falloff_sources' rows; o32, d (M,3) the emitted rays, t32 (M,)
    their hit distances, geom (M,) < 0 for a miss, slot (M,) each photon's emission slot;
    power (M,3) scaled in place."""
    centre, r2, ends = soft
    rows = np.flatnonzero(geom >= 0)
    if not len(rows):
        return
    if len(ends) == 1:
        # One light (soft, or there would be no table): its centre and r^2 for every
        # slot, broadcast (the same values as a row per slot).
        c, rr = centre[0], r2[0]
    else:
        k = np.searchsorted(ends, slot[rows], side="right")
        keep = r2[k] > 0.0
        rows, k = rows[keep], k[keep]
        c, rr = centre[k], r2[k]
    if len(rows) == len(geom):  # every photon hit: no gathers
        p = o32.astype(np.float64)
        p += t32.astype(np.float64)[:, None] * d
    else:
        p = np.take(o32, rows, axis=0).astype(np.float64)
        p += np.take(t32, rows).astype(np.float64)[:, None] * np.take(d, rows, axis=0)
    p -= c
    dist2 = np.einsum("ij,ij->i", p, p)
    f = (dist2 / (dist2 + rr))[:, None].astype(power.dtype)
    if len(rows) == len(geom):
        power *= f
    else:
        power[rows] *= f


def _closest_hits(accel, o32, d32, tfar32, out):
    """Closest hits of the photon rays o32, d32 (N,3) float32 over every triangle, as
    Accel.intersect_hits answers: (geom, prim (N,) int32, u, v (N,) float32, starts),
    written into out = (geom, prim, u, v) (the trace's pooled buffers) where the BVH
    takes them. A VisibilityAccel's queries without a ray class go to its `full` BVH; a
    BVH without intersect_hits (two-level instances) answers through intersect,
    converted."""
    full = getattr(accel, "full", accel)
    if hasattr(full, "intersect_hits"):
        return full.intersect_hits(o32, d32, tfar32, out)
    t, prim, u, v = accel.intersect(o32, d32)  # unbounded, as tfar32
    tfar32[:] = t  # the hit distance, as Embree writes it (inf: a miss)
    geom, prim32, starts = rows_as_hits(prim)
    return geom, prim32, u.astype(np.float32), v.astype(np.float32), starts


def _needs_numpy_hits(table) -> bool:
    """Surface data from bsdf.surface_hit (numpy texture, normal-map and alpha-texture
    evaluation) rather than the photon_surfaces kernel."""
    return any(x is not None for lst in (table.textures, table.normal_maps,
                                         table.alpha_textures, table.scalar_textures)
               for x in (lst or ()))


