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
which never increases a photon's power).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .lights.group import photon_emitters
from .parallel import Cancelled, chunk_length, ordered_map
from .bsdf import GLASS_R, GLASS_T, LOBE_NAMES, lobe_weights, sample_specular, surface_hit
from .normalmap import bump_shadowing
from .sampling import cosine_hemisphere, dot, max3, to_world
from .geometry import CAMERA
from .visibility import ALL_RAYS, DIFFUSE, SHADOW, continued_class

DIRECT, CAUSTIC, INDIRECT, CAUSTIC_DIFFUSE = 0, 1, 2, 3
LOBES = LOBE_NAMES
# The ray kinds a photon segment can stand for on the camera side (camera rays start at
# the camera, never at a photon's surface).
SEGMENT_KINDS = ALL_RAYS & ~CAMERA


@dataclass
class Photons:
    position: np.ndarray   # (N,3) float32, re-centred world space
    power: np.ndarray      # (N,3) float32 watts
    direction: np.ndarray  # (N,3) float32 travel direction when it arrived
    normal: np.ndarray     # (N,3) float32 surface normal on the side it arrived from
    kind: np.ndarray       # (N,) uint8 DIRECT / CAUSTIC / INDIRECT
    emitted: int = 0       # photons emitted to produce these (for statistics)

    @classmethod
    def empty(cls):
        z = np.zeros((0, 3), np.float32)
        return cls(z, z.copy(), z.copy(), z.copy(), np.zeros(0, np.uint8))

    def __len__(self):
        return len(self.position)

    def select(self, mask) -> "Photons":
        return Photons(self.position[mask], self.power[mask], self.direction[mask],
                       self.normal[mask], self.kind[mask], self.emitted)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.position, self.power, self.direction,
                                      self.normal, self.kind))


def trace_photons(ctx, lights, counts, caustic_only: bool, stream: int, progress=None,
                  should_cancel=None, targets=None, first_hit=None) -> Photons:
    """Emit counts[i] photons from lights[i] and trace them. caustic_only: keep L S+ D
    paths only and stop a photon as soon as it scatters diffusely (the caustic shot).
    targets=(centers, radii): aim the photons at these bounding spheres (caustic casters).
    first_hit=(is_caster, keep): is_caster (objects,) bool by object id; store CAUSTIC
    photons only if whether the first surface they hit belongs to a caster equals keep.
    An aimed shot (keep=True) and an unaimed one (keep=False) thus split the L S+ D paths
    between them without overlap: a path whose first hit is a caster starts inside that
    caster's bounding sphere, which the aimed shot covers (engine/render.py)."""
    settings = ctx.settings
    total = int(sum(counts))
    jobs = []
    # Many lights with few photons each emit in groups (engine/lights/group.py).
    for li, emitter, count in photon_emitters(lights, counts, settings.chunk_size):
        chunk = chunk_length(count, settings.chunk_size)  # same for any thread count
        jobs += [(li, ci, start, min(chunk, count - start), count, emitter)
                 for ci, start in enumerate(range(0, count, chunk))]
    threads = settings.threads
    accel = ctx.accel.serial() if threads > 1 and len(jobs) > 1 else ctx.accel

    def job(item, stop):
        li, ci, start, n, count, emitter = item
        rng = np.random.default_rng([settings.seed, stream, li, ci])
        return _trace_chunk(ctx, accel, emitter, n, count, rng, caustic_only, targets, stop,
                            first_hit)

    parts = {k: [] for k in ("position", "power", "direction", "normal", "kind")}
    done = 0
    for item, chunk_parts in zip(jobs, ordered_map(job, jobs, threads, should_cancel)):
        for k, v in chunk_parts.items():
            parts[k] += v
        done += item[3]
        if progress is not None:
            label = "caustic photons" if caustic_only else "photons"
            progress("photons", done / max(total, 1), f"Tracing {label} {_k(done)}/{_k(total)}")
    if not parts["position"]:
        out = Photons.empty()
    else:
        out = Photons(**{k: np.concatenate(v) for k, v in parts.items()})
    out.emitted = total
    return out


def _trace_chunk(ctx, accel, light, n, count, rng, caustic_only, targets, should_cancel,
                 first_hit=None):
    """Emit n of the light's `count` photons and trace them; returns the stored hits as
    lists of arrays, bounce by bounce."""
    geo, table, settings = ctx.geo, ctx.table, ctx.settings
    parts = {k: [] for k in ("position", "power", "direction", "normal", "kind")}
    if targets is None:
        o, d, power = light.emit(n, rng)
    else:
        o, d, power = light.emit_towards(n, rng, *targets)
    power *= n / count  # emit() spreads the light's whole flux over this chunk
    live = max3(power) > 0  # e.g. aimed outside a one-sided light's hemisphere
    # Each photon keeps its slot in the chunk and takes the random numbers of that slot,
    # drawn for every slot at every bounce: a photon whose path changes (a hit a hair
    # from an edge, rounded differently in a scaled scene) does not shift the random
    # numbers, and so the paths, of all the photons after it.
    slot = np.nonzero(live)[0]
    if not live.all():
        o, d, power = o[live], d[live], power[live]
    had_diffuse = np.zeros(len(o), bool)
    had_specular = np.zeros(len(o), bool)
    caustic_then_diffuse = np.zeros(len(o), bool)  # path so far: L S+ D S*
    first_caster = None  # per photon: its first hit was on a caster (with first_hit)
    # Ray visibility (docs/scene_format.md, "Ray visibility"). A segment arriving at a
    # surface stands for the camera-side ray that leaves that surface backwards; its kind
    # is set by the use made of the photon there (stored, or continued with a lobe: see
    # below). `kinds` holds, per photon, the ray kinds for which the segment so far is a
    # valid camera-side ray: the surface it left sees them (the ray must hit it; a light
    # always does) and nothing in between that they see lies in the way.
    # The first segment also needs the light to be visible to the kind it stands for
    # (Light.ray_kinds: a light object's diffuse / glossy / transmission visibility).
    light_kinds = int(light.ray_kinds) & SEGMENT_KINDS
    vis_on = bool(getattr(accel, "has_invisible", False)) or light_kinds != SEGMENT_KINDS
    kinds = np.full(len(o), light_kinds, np.int64)
    for bounce in range(settings.max_photon_depth):
        if should_cancel is not None and should_cancel():
            raise Cancelled()
        if len(o) == 0:
            break
        bounce_rng = np.random.default_rng(rng.integers(1 << 62))
        xi_all = bounce_rng.random((3, n))  # roulette, diffuse direction (2) per slot
        _, prim, u, v = accel.intersect(o, d)
        alive = prim >= 0
        if not alive.all():
            o, d, power, prim, u, v = o[alive], d[alive], power[alive], prim[alive], u[alive], v[alive]
            slot = slot[alive]
            had_diffuse, had_specular = had_diffuse[alive], had_specular[alive]
            caustic_then_diffuse = caustic_then_diffuse[alive]
            kinds = kinds[alive]
            if first_caster is not None:
                first_caster = first_caster[alive]
        if len(o) == 0:
            break
        if first_hit is not None and first_caster is None:
            first_caster = np.take(first_hit[0], np.take(geo.object_id, prim))
        hit = surface_hit(geo, table, prim, u, v, d)
        carry = None
        if vis_on:
            hit_vis = np.take(geo.visibility, prim).astype(np.int64)
            # The photon stops here for every kind it still has: this surface is where
            # the camera-side ray starts, and a ray never tests its own start. For the
            # kinds that do not see this surface it is also not there: a split-off copy
            # with those kinds passes on behind it, keeping the photon's slot (its
            # random numbers).
            behind = kinds & ~hit_vis
            thru = np.nonzero(behind)[0]
            if len(thru):
                carry = (hit.clear(thru, d[thru]), d[thru],
                         power[thru], had_diffuse[thru], had_specular[thru],
                         caustic_then_diffuse[thru], behind[thru], slot[thru])
                if first_caster is not None:
                    carry += (first_caster[thru],)
        w = lobe_weights(table, hit)
        # Bent normals (Normal Map / Bump): the diffuse lobe takes Cycles' bump shadowing
        # term for the photon's arriving direction, stored and bounced alike.
        bump = (None if hit.n_smooth is None
                else bump_shadowing(hit.n_smooth, hit.ns, -d)[:, None])
        kind = np.where(had_diffuse, np.where(caustic_then_diffuse, CAUSTIC_DIFFUSE, INDIRECT),
                        np.where(had_specular, CAUSTIC, DIRECT))
        store = max3(w["diffuse"]) > 0
        if caustic_only:
            store &= kind == CAUSTIC
        if first_caster is not None:
            store &= (kind != CAUSTIC) | (first_caster == bool(first_hit[1]))
        if vis_on:
            # Stored for lookups at this surface: the camera side reaches the photon's
            # source from here with a shadow ray (direct light) or a diffuse ray.
            diffuse_use = np.where(kind == DIRECT, SHADOW, DIFFUSE)
            store &= (kinds & diffuse_use) != 0
        if store.any():
            parts["position"].append(hit.p[store].astype(np.float32))
            parts["power"].append((power[store] if bump is None else
                                   power[store] * bump[store]).astype(np.float32))
            parts["direction"].append(d[store].astype(np.float32))
            parts["normal"].append(hit.ng[store].astype(np.float32))
            parts["kind"].append(kind[store].astype(np.uint8))
        # Russian roulette over the lobes.
        probs = np.stack([max3(w[k]) for k in LOBES], axis=1)
        s = probs.sum(axis=1)
        probs = probs / np.maximum(s, 1.0)[:, None]
        cdf = np.cumsum(probs, axis=1)
        xi = xi_all[0, slot]
        lobe = np.count_nonzero(xi[:, None] >= cdf, axis=1)  # len(LOBES) = absorbed
        survive = lobe < len(LOBES)
        if caustic_only:
            survive &= lobe != 0
        idx = np.nonzero(survive)[0]
        lobe = lobe[idx]
        # glass_r and glass_t are sampled as one lobe (bsdf.sample_specular)
        glass = (lobe == GLASS_R + 1) | (lobe == GLASS_T + 1)
        p_sel = np.where(glass, probs[idx, GLASS_R + 1] + probs[idx, GLASS_T + 1],
                         probs[idx, lobe])
        # The chosen lobe's weight, row by row, without an (n,6,3) stack.
        w_sel = np.zeros((len(idx), 3))
        for li, k in enumerate(LOBES):
            rows = np.nonzero(lobe == li)[0]
            if len(rows):
                w_sel[rows] = np.take(w[k], idx[rows], axis=0)
        new_power = power[idx] * w_sel / np.maximum(p_sel, 1e-300)[:, None]
        sub = hit.take(idx)
        slot = slot[idx]
        new_d = np.empty((len(idx), 3))
        ok = np.ones(len(idx), bool)
        diff = lobe == 0
        if diff.any():
            nd = to_world(cosine_hemisphere(xi_all[1, slot[diff]], xi_all[2, slot[diff]]),
                          sub.ns[diff])
            new_d[diff] = nd
            ok[diff] = dot(nd, sub.ng[diff]) > 0
            if bump is not None:
                new_power[diff] *= bump[idx[diff]]
        spec = ~diff
        if spec.any():
            spec_rows = np.nonzero(spec)[0]
            sd, valid, transmitted, weight = sample_specular(table, sub.take(spec_rows),
                                                             lobe[spec] - 1, bounce_rng)
            new_d[spec] = sd
            ok[spec] = valid
            # The sampled direction's own weight replaces the lobe's estimated albedo.
            new_power[spec_rows] = (power[idx[spec_rows]] * weight
                                    / np.maximum(p_sel[spec_rows], 1e-300)[:, None])
            # The glass lobe's sample decides reflect / refract (its visibility class too).
            lobe[spec_rows] = np.where(glass[spec_rows], np.where(transmitted, GLASS_T + 1,
                                                                  GLASS_R + 1),
                                       lobe[spec_rows])
            # Refraction: radiance is carried as invariant across the interface, as the
            # camera side (no eta^2 factor) and Cycles do, so the photon's power takes
            # the factor (eta_i / eta_t)^2 (docs/units.md, "Refraction"). Paired
            # interfaces (a slab, a ball) cancel it exactly.
            refracted = spec_rows[transmitted & glass[spec_rows]]
            if len(refracted):
                ior = np.take(table.ior, sub.mat[refracted])
                eta_ratio = np.where(sub.front[refracted], 1.0 / ior, ior)
                new_power[refracted] *= (eta_ratio * eta_ratio)[:, None]
        if vis_on:
            # Continued with a lobe: the arriving segment is the camera-side ray of that
            # lobe's kind leaving here backwards - a diffuse bounce uses the same kinds as
            # storing (direct light at a diffuse surface comes from shadow rays), a
            # mirror / glass lobe glossy or transmission (continued_class). It must be
            # among the kinds the segment is valid for. The next segment is valid for the
            # kinds that see this surface. A transparent pass continues the same
            # camera-side ray: it keeps its kinds, less those that do not see this
            # surface (they went on in the split-off copy).
            kinds_in = kinds[idx]
            vis_here = hit_vis[idx]
            use = np.where(kind[idx] == DIRECT, SHADOW, DIFFUSE)
            if spec.any():
                use[spec] = continued_class(lobe[spec] - 1, 0)
            passing = lobe == 1
            ok &= passing | ((kinds_in & use) != 0)
            new_kinds = np.where(passing, kinds_in & vis_here, vis_here & SEGMENT_KINDS)
            ok &= new_kinds != 0
        else:
            new_kinds = kinds[idx]
        ctd = caustic_then_diffuse[idx]
        if first_caster is not None:
            first_caster = first_caster[idx]
        first_diffuse = diff & ~had_diffuse[idx]
        # The first diffuse bounce after a caustic path starts L S+ D; any further
        # diffuse bounce makes it ordinary indirect light.
        caustic_then_diffuse = np.where(diff, first_diffuse & had_specular[idx], ctd)
        had_diffuse = had_diffuse[idx] | diff
        # A transparent pass (lobe 1) leaves the path's kind as it was: shadow rays cross
        # transparent surfaces (engine/shadowtransmittance.py), so light through them is
        # direct light, not a caustic (docs/design.md, Transparent shadows).
        had_specular = had_specular[idx] | (spec & (lobe != 1))
        # isfinite(all) and max > 0 per row in one pass: max3 propagates NaN
        # (NaN > 0 is False) and inf is caught by isfinite of the row sum.
        mx = max3(new_power)
        keep = ok & np.isfinite(new_power[:, 0] + new_power[:, 1] + new_power[:, 2]) & (mx > 0)
        new_d, new_power = new_d[keep], new_power[keep]
        slot = slot[keep]
        had_diffuse, had_specular = had_diffuse[keep], had_specular[keep]
        caustic_then_diffuse = caustic_then_diffuse[keep]
        kinds = new_kinds[keep]
        if first_caster is not None:
            first_caster = first_caster[keep]
        o = sub.clear(keep, new_d)
        d, power = new_d, new_power
        if carry is not None:
            (o, d, power, had_diffuse, had_specular, caustic_then_diffuse, kinds,
             slot) = (np.concatenate([a, b]) for a, b in zip(
                (o, d, power, had_diffuse, had_specular, caustic_then_diffuse, kinds,
                 slot), carry[:8]))
            if first_caster is not None:
                first_caster = np.concatenate([first_caster, carry[8]])
    return parts


def _k(n: int) -> str:
    return f"{n / 1000:.0f}k" if n >= 1000 else str(n)
