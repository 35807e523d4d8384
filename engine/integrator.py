"""Pass 2: camera rays, specular chains, and the radiance at each diffuse hit.

At every camera-path hit the diffuse lobe is evaluated as
    direct   shadow rays to every light (area lights sampled: soft shadows)
    caustic  caustic map estimate (L S+ D light)
    indirect final gather into precomputed photon irradiance, or the global map directly
and one specular lobe (mirror, glass, coat, pass-through) is continued, chosen at random
in proportion to its weight. Contributions after a specular bounce go to the `specular`
pass, so the passes add up to the combined image.
"""
from __future__ import annotations

import functools
import math
import threading
from dataclasses import dataclass, field, replace

import numpy as np

from .lightlinking import receiver_link, tree_pmf
from .directlight import (CUT_DIFFUSE, CUT_GLOSSY, NO_HROWS, NO_ROWS, NO_ROWS3, ONE_BELOW,
                          DirectLightBuffers, direct_light, sample_lights, terminator_lift)
from .normalmap import bump_shadowing
from .lights import AREA, MESH, POINT, SPOT, SUN
from .scene import DISK
from .lights.area import MIN_SPHERICAL_SOLID_ANGLE, rect_solid_angles
from .lights.point import sphere_light_pdf
from .lights.selection import empty_tree, selection_samples, selector_for
from .lights.world import WORLD
from .lights.packing import pack_lights
from . import (adaptive, aopass, chaincounts, datapasses, heterogeneous, lightpasses, media,
               photonvisibility, raymaterials, sampleclamp, shadelight, subsurfacewalk,
               volumeemission,
               vectorpass, volumescatter, volumewalk, worldmedium)
from .bump import camera_differential, transfer_footprint
from .bsdf import (GLASS_R, GLASS_T, SPEC_LOBES, _hit_alpha, closures, lobe_weights,
                   plain_surfaces, reads_footprint, surface_hit, surface_hit_lobes)
from .camerakernels import (_PASS as PASS_LOBE, choose_lobes, continue_lobes, film_add,
                            film_add_scalar, film_first_normals, gather_rays, keep_path_hits,
                            mirror_survival, pick_lobes, shade_lobes)
from .camerarays import camera_rays_kernel, chunk_samples
from .gatherkernels import (add_gathered, count_bounces, diffuse_lookups, keep_embree_hits,
                            keep_hits, lean_diffuse, lean_materials, rays_f32)
from .anisotropy import anisotropic_materials, set_hit_tangents
from .closures import principled as pr
from .coincident import CoincidentSurfaces
from .turnedlight import TurnedReflections
from . import turnedglossy
from .photonkernels import B_TOTAL
from . import glossysplit
from . import blurredpassage
from .console import short_count
from .filterglossy import NO_BLUR, PathBlur
from .glasslight import rough_transmission_rows, transmitted_light
from .parallel import Cancelled, chunk_length, ordered_map
from .pixelfilter import filter_table
from .guiding import warp as guide_warp
from .sampling import SampleDimensions, StratifiedSampler, dot, max3
from .panelight import pane_irradiance, panes_for
from .shadelight import shade_bsdf_weights, shade_light, shades_for
from .mediumstart import point_medium
from .shadowtransmittance import CameraPassages, ShadowTransmittance
from .gatherpassages import GatherPassages
from .visibility import CAMERA, DIFFUSE, GLOSSY, SHADOW, SPEC_LOBE_CLASS, TRANSMISSION


@dataclass
class Counters:
    """Rays and hits of a camera pass. stages: finer counts, (stage, depth) -> count:
    ("paths", b) camera paths traced at bounce b; ("shaded", b) their hits that took the
    diffuse lobe's terms; ("camera shadow", b) shadow rays from those hits; ("gather", L)
    final-gather rays (continuations through glass and mirrors included) at gather level
    L (0: from the camera's hits; L > 0: regathers); ("regathered", L) gather ends
    gathered again at level L; ("regather shadow", L) their shadow rays
    (bench/bench_window_room.py prints them)."""
    camera_rays: int = 0
    shadow_rays: int = 0
    gather_rays: int = 0
    specular_rays: int = 0
    diffuse_hits: int = 0
    stages: dict = field(default_factory=dict)

    def add(self, other: "Counters"):
        for name in self.__dataclass_fields__:
            if name == "stages":
                for key, value in other.stages.items():
                    self.count(key[0], key[1], value)
            else:
                setattr(self, name, getattr(self, name) + getattr(other, name))

    def count(self, stage: str, depth: int, n: int):
        """Add n to the finer count (stage, depth)."""
        key = (stage, int(depth))
        self.stages[key] = self.stages.get(key, 0) + int(n)

    def stage_table(self) -> dict:
        """stages as 'stage depth' -> count, in stage order (for a render's stats)."""
        return {f"{k[0]} {k[1]}": v for k, v in sorted(self.stages.items())}


def camera_rays(camera, offset, width, height, px, py, jx, jy, filter_table=None, lens=None):
    """World rays (re-centred) through image positions (px + jx, py + jy); rows top-down.
    filter_table (engine/pixelfilter.py): jx, jy are uniform numbers in [0, 1) that the
    pixel filter's inverse CDF turns into positions (None or empty: positions as given).
    lens: (u1, u2) (N,) uniform numbers placing each ray on the camera's aperture (depth
    of field, Camera.aperture_radius > 0); None: every ray through the lens centre (the
    pinhole ray, sharp at every depth).
    A panoramic camera (Camera.panorama) maps the positions to directions
    (engine/panorama.py); outside its lens a ray's distance limit is 0.
    Returns origins, unit directions, and the distance limits (clip start / end).
    One compiled kernel (engine/camerarays.py)."""
    hw, hh = camera.half_extents(width, height)
    R = np.ascontiguousarray(camera.rotation, dtype=np.float64)
    pos = np.asarray(camera.position - offset, dtype=np.float64)
    return camera_rays_kernel(camera.kind == "ORTHO", float(hw), float(hh),
                              float(camera.shift_x), float(camera.shift_y), R, pos,
                              float(camera.clip_start), float(camera.clip_end), int(width),
                              int(height), np.ascontiguousarray(px), np.ascontiguousarray(py),
                              np.ascontiguousarray(jx, dtype=np.float64),
                              np.ascontiguousarray(jy, dtype=np.float64),
                              np.ascontiguousarray(np.empty(0) if filter_table is None
                                                   else filter_table, dtype=np.float64),
                              float(camera.aperture_radius), float(camera.focus_distance),
                              int(camera.aperture_blades), float(camera.aperture_rotation),
                              1.0 / float(camera.aperture_ratio),
                              *(( _EMPTY_F, _EMPTY_F) if lens is None or not camera.has_dof
                                else (np.ascontiguousarray(lens[0], dtype=np.float64),
                                      np.ascontiguousarray(lens[1], dtype=np.float64))),
                              _EMPTY_F if camera.panorama is None
                              else camera.panorama.pack(width, height, camera.sensor_fit))


_EMPTY_F = np.zeros(0)


def _passage_filter_glossy(ctx, shadow) -> float:
    """The Filter Glossy the shadow rays' window glass takes (directlight.direct_light's
    filter_glossy): the render's, where blurredpassage.CYCLES_BLUR and the scene has flat
    passages; else 0.0."""
    if not blurredpassage.CYCLES_BLUR or shadow is None or not shadow.flat_on:
        return 0.0
    fg = float(getattr(ctx.settings, "cycles_filter_glossy", 0.0) or 0.0)
    return fg if fg > 0.0 else 0.0


def direct_irradiance(ctx, hit, rng, counters: Counters, sampler=None,
                      skip_mesh_lights=False, bsdf=None, buffers=None, rows=None,
                      counts=None, shade_glossy=None, glossy_out=None,
                      used=None, world_gather=None) -> np.ndarray:
    """Irradiance (N,3) at the hits from all lights by shadow rays (one ray per sample,
    tested for occlusion), in the compiled kernels of engine/directlight.py.
    skip_mesh_lights: leave emissive meshes to the caller (a recursive gather finds them
    by its own rays, which stays calm right next to the emitter).
    bsdf = (fd (N,3) diffuse f, prm (N,P) the hits' packed lobes, sel (N, N_LOBES) the
    continuation's lobe-choice probabilities): outgoing radiance instead, the diffuse f
    plus the rough reflective lobes' f, in full for delta lights and weighted by multiple
    importance sampling for the lights the continuation also finds (light_modes,
    directlight.accumulate_bsdf).
    buffers: the calling thread's directlight.DirectLightBuffers (the result is then
    their sums, valid until their next use; None: fresh arrays).
    rows (K,) int64: shade these rows of hit only (the result, the sampler and bsdf's fd
    are per row of rows; bsdf's prm and sel are the whole batch's, read at rows): the
    same numbers as hit.take(rows) without copying the rows' fields; None: every hit.
    counts: (4,) or (n,4) int64, the camera-side bounce counts the hits are reached with
    (B_TOTAL order; None: none, the camera's first hits): shadow rays through flat glass
    passages cross only as many as the bounce limits allow (chaincounts.flat_passages);
    with bsdf per lobe kind (the diffuse f and sheen as a diffuse bounce, the other rough
    reflective lobes as a glossy one: directlight.accumulate_bsdf's cut).
    With bsdf, a light lights only the lobes its ray visibility allows (lobe_cut), each
    light sampled on its own (with the light tree its members light every lobe).
    shade_glossy: None, or an (n,) bool array set True at the rows whose rough reflective
    lobes took the lamps through shades (shadelight.shade_light's glossy: the
    continuation that meets the shade from them is then MIS-weighted,
    shadelight.shade_bsdf_weights); False elsewhere.
    glossy_out: None, or an (n,3) zero array that receives, with bsdf, the rough
    reflective lobes' part of the result, sheen aside (Cycles counts sheen as diffuse;
    the light passes' Glossy Direct, engine/lightpasses.py): direct_light's glossy.
    used: (n,) int64, the transparent bounces each hit's camera path made before it: its
    shadow rays cross that many fewer transparent surfaces (Cycles' transparent_bounce,
    path-wide; directlight.direct_light's used); None: 0 (first hits).
    world_gather: (li, G) of integrator.world_gather: the constant world li's shadow rays
    each count 1 / (n_s + G) (the hits' G gather rays that escape count the rest: the
    caller's); None: 1 / n_s."""
    n = len(hit.p) if rows is None else len(rows)
    chosen = selector_for(ctx, skip_mesh_lights)
    light_cut = None
    if bsdf is not None and (chosen is None or glossy_only_lights(ctx)):
        # (with the light tree only for the lamps only glossy rays see: the tree's
        # members light every lobe, its entries take no cut)
        light_cut = np.array([lobe_cut(light) for light in ctx.lights], np.int64)
        if not light_cut.any():
            light_cut = None
    samples = light_sample_list(ctx, n, rng, sampler, skip_mesh_lights,
                                reflection=light_cut is not None)
    if n == 0 or not samples:
        return np.zeros((n, 3))
    if world_gather is not None:
        # (the kernels divide each entry by its count: a float is taken as it is)
        wli, G = world_gather
        samples = [(li, tr, cnt + G if li == wli else cnt, u1, u2, s3)
                   for li, tr, cnt, u1, u2, s3 in samples]
    packed = ctx.packed_lights or pack_lights(ctx.lights)
    if bsdf is not None:
        fd, prm, sel = bsdf
        if chosen is not None:
            # The tree picks the light per hit: the kernel weights a delta light's sample
            # by the full BSDF, a light with a size by MIS with the tree's choice
            # probability in its pdf (mode 3).
            mode = np.full(len(ctx.lights),
                           MODE_TREE if ctx.plan.specular_depth > 0 else MODE_DELTA, np.int64)
        else:
            mode = light_modes(ctx, reflection=light_cut is not None)
        bsdf = (np.ascontiguousarray(fd, np.float64), np.ascontiguousarray(prm),
                np.ascontiguousarray(hit.wo, np.float64), mode,
                np.ascontiguousarray(sel, np.float64))
    shadow = getattr(ctx, "shadow", None)
    passages = None
    if shadow is not None and shadow.flat_on:
        c = (0, 0, 0, 0) if counts is None else counts
        limits = ctx.settings.bounce_limits
        cap = chaincounts.flat_passages(c, limits)
        gcap = (chaincounts.flat_passages(c, limits, chaincounts.GLOSSY) if bsdf is not None
                else cap)
        # A passage is two of a shadow ray's max_hits surfaces: caps at or above
        # max_hits // 2 never bind (the default limits at the camera's hits).
        bind = shadow.max_hits // 2
        if min(cap.min(), gcap.min()) < bind:
            if np.array_equal(np.minimum(cap, bind), np.minimum(gcap, bind)):
                passages = np.ascontiguousarray(np.broadcast_to(cap, (n,)), np.int64)
            else:
                # The lobes' caps differ: both, per hit (directlight.direct_light).
                passages = np.ascontiguousarray(
                    np.broadcast_to(np.stack([cap, gcap], axis=-1), (n, 2)), np.int64)
    link = receiver_link(ctx, hit, rows, skip_mesh_lights)
    # The glossy lobes' part, summed beside E from the same entries (no number drawn:
    # the image keeps its bits); with Light Linking by a second pass (below).
    g_out = glossy_out if bsdf is not None and link is None else None
    E, rays = direct_light(packed, _hit_arrays(ctx.geo, hit, rows), samples, ctx.accel,
                           SHADOW, n, shadow=shadow,
                           tree=None if chosen is None else chosen[1],
                           bsdf=bsdf, buffers=buffers, rows=rows, passages=passages,
                           light_cut=light_cut, medium_sigma=_medium_sigma(ctx, hit, rows),
                           world_sigma=_world_sigma(ctx, hit, rows) if shadow is not None
                           else None, link=link, glossy=g_out, used=used,
                           filter_glossy=_passage_filter_glossy(ctx, shadow))
    counters.shadow_rays += rays
    if glossy_out is not None and bsdf is not None and link is not None:
        # Light Linking splits the hits by receiver set: the same samples again with the
        # diffuse f at 0 (fresh buffers; sheen's light then counts as glossy).
        glossy_out += direct_light(
            packed, _hit_arrays(ctx.geo, hit, rows), samples, ctx.accel, SHADOW, n,
            shadow=shadow, tree=None if chosen is None else chosen[1],
            bsdf=(np.zeros_like(bsdf[0]),) + bsdf[1:], rows=rows, passages=passages,
            light_cut=light_cut, medium_sigma=_medium_sigma(ctx, hit, rows),
            world_sigma=_world_sigma(ctx, hit, rows) if shadow is not None else None,
            link=link, used=used, filter_glossy=_passage_filter_glossy(ctx, shadow))[0]
    if shade_glossy is not None:
        shade_glossy[:] = False
    panes, shades = panes_for(ctx), shades_for(ctx)
    if panes is None and (shades is None or rng is None):
        return E
    # Light through a pane or a shade is, to Cycles, a diffuse bounce at the hit that BSDF
    # sampling continues (the pane's refraction / the shade's direct light are the light's
    # side): Light Paths' Diffuse and Max must allow one more bounce, as for the final
    # gather (review32, live Cycles: at Diffuse 0 it reads 0 there; at Diffuse 1 our
    # regathered points took their pane light beyond the limit, +17 %). Rows beyond the
    # limits take none.
    c = np.zeros((n, 4), np.int64) if counts is None else np.broadcast_to(counts, (n, 4))
    reach = chaincounts.within(c + np.array([1, 1, 0, 0], np.int64),
                               ctx.settings.bounce_limits)
    # The rows that take it: within the limits, with a diffuse lobe. Their hit data and
    # light samples are gathered once for both estimators.
    diffuse = reach if bsdf is None else reach & (bsdf[0].max(axis=1) > 0.0)
    # The rough reflective lobes take the lamps through shades too (shadelight.shade_light,
    # MIS against the continuation that meets the shade): light through a shade is to
    # them a glossy bounce (Cycles' count: as the continuation's), so their limits are
    # those of a glossy bounce, which the continuation's own hit checks.
    gloss = None
    if bsdf is not None and shades is not None and rng is not None and shadelight.SERVE_GLOSSY:
        prm_b = bsdf[1] if rows is None else np.take(bsdf[1], rows, axis=0)
        rough = np.empty(n, np.bool_)
        pr.rough_reflection_rows(np.ascontiguousarray(prm_b), rough)
        gloss = rough & chaincounts.within(c + np.array([1, 0, 1, 0], np.int64),
                                           ctx.settings.bounce_limits)
        if not gloss.any():
            gloss = None
    pts = np.flatnonzero(diffuse if gloss is None else diffuse | gloss)
    if not len(pts):
        return E
    at = pts if rows is None else np.take(rows, pts)
    p_, ns_, ng_ = (np.take(np.asarray(a, np.float64), at, axis=0)
                    for a in (hit.p, hit.ns, hit.ng))
    offset_ = np.take(np.asarray(hit.offset, np.float64), at)
    sub = [(li, tr, cnt, u1[pts], u2[pts], None if s3 is None else s3[pts])
           for li, tr, cnt, u1, u2, s3 in samples]
    fd = None if bsdf is None else bsdf[0][pts]
    used_ = None if used is None else np.take(np.asarray(used, np.int64), pts)
    if panes is not None:
        # Suns and the world through single-plane glass panes (engine/panelight.py): the
        # diffuse lobe's light, which the photons through the panes no longer carry as
        # caustics.
        Ep, rays = pane_irradiance(ctx, panes, p_, ns_, ng_, offset_, sub, used=used_)
        counters.shadow_rays += rays
        E[pts] += Ep if fd is None else Ep * fd
    if shades is not None and rng is not None:
        # Lamps through Translucent BSDF and rough glass shades (engine/shadelight.py):
        # the diffuse lobe's light, which the photons through the shades no longer carry
        # as caustics.
        glossy = None
        if gloss is not None:
            # The continuation's lobe-choice probabilities (none where it makes none:
            # psum 0 rows carry sel 0 from lobe_choice) and whether it exists at all:
            # without continuation (specular effects off) the samples count in full.
            glossy = (np.take(bsdf[1], at, axis=0), np.take(bsdf[4], at, axis=0),
                      np.take(np.asarray(hit.wo, np.float64), at, axis=0),
                      ctx.plan.specular_depth > 0)
        Es, Lg, rays = shade_light(ctx, shades, p_, ns_, ng_, offset_, sub, rng, glossy,
                                   used=used_)
        counters.shadow_rays += rays
        if fd is not None:
            Es = Es * fd
        if gloss is not None:
            Es[~diffuse[pts]] = 0.0
            g_on = gloss[pts]
            Es[g_on] += Lg[g_on]
            if glossy_out is not None:
                glossy_out[pts[g_on]] += Lg[g_on]
            if shade_glossy is not None:
                shade_glossy[pts[g_on]] = True
        E[pts] += Es
    return E


def _medium_sigma(ctx, hit, rows):
    """(n,3) the extinction of the medium each shaded hit (rows of hit, None: all) is in
    (hit.medium, set by the camera paths; a hit on the medium's own surface, or in no
    known medium: 0), or None when no hit is in one: the shadow rays that meet no surface
    on their way lie wholly in it (directlight.direct_light)."""
    med = getattr(hit, "medium", None)
    if med is None:
        return None
    med = np.asarray(med if rows is None else np.take(med, rows), np.int64)
    mat = np.asarray(hit.mat if rows is None else np.take(hit.mat, rows), np.int64)
    inside = (med >= 0) & (med != mat)
    if not inside.any():
        return None
    sigma = media.absorption_table(ctx.table)
    out = np.zeros((len(med), 3))
    out[inside] = sigma[med[inside]]
    return out


def _world_sigma(ctx, hit, rows):
    """(n,3) the world volume's extinction at the shaded hits (rows of hit, None: all)
    that are in it (hit.medium its row: engine/worldmedium.py), 0 at the others, or None
    without a world volume: shadow rays crossing transparent surfaces keep exp(-sigma_t
    length) of it (directlight.direct_light)."""
    row = worldmedium.medium_row(ctx)
    out = _medium_sigma(ctx, hit, rows) if row >= 0 else None
    if out is not None:
        med = np.asarray(hit.medium if rows is None else np.take(hit.medium, rows))
        out[med != row] = 0.0  # (the hits in an object's medium: not the world's)
    return out


def lobe_cut(light) -> int:
    """The lobes a light's shadow rays may not light (directlight.CUT_DIFFUSE,
    CUT_GLOSSY), by its ray visibility, as Cycles' _shader_bsdf_exclude at a light sample
    (intern/cycles/kernel/integrator/surface_shader.h: SHADER_EXCLUDE_DIFFUSE drops the
    diffuse, sheen and translucent closures, SHADER_EXCLUDE_GLOSSY the glossy ones; a
    reflected ray sees the lamp by is_light_shader_visible_to_path): a lamp with
    Glossy visibility off lights a diffuse surface but throws no highlight; one with
    Diffuse off only highlights. Emissive meshes and the world: none (their visibility
    lives on their triangles)."""
    cut = 0
    if not light.ray_kinds & SHADOW:
        cut |= CUT_DIFFUSE
    if not light.ray_kinds & GLOSSY:
        cut |= CUT_GLOSSY
    return cut


def light_sample_list(ctx, n, rng, sampler=None, skip_mesh_lights=False, modes=None,
                      reflection=False) -> list:
    """The light samples of n hits, as directlight.direct_light takes them: a list of
    (light index, traced?, the light's sample count, u1 (n,), u2 (n,), third number (n,)
    or None), in the order they are drawn and summed. With many lights (the light tree,
    lights/selection.py) selection_samples entries of light index -1, the third number
    the tree's choice; else each light's plan.light_samples entries in light order, the
    third number a mesh light's triangle or an environment map's strategy.
    sampler: the camera's StratifiedSampler (its 2-D dimensions ("light", li, si), the
    choices stratified with the point: mesh_light_numbers) or None (rng draws u1, u2 and
    the third number together, in this order).
    skip_mesh_lights: no samples of emissive meshes (a recursive gather finds them by its
    own rays). modes (L,) int (light_modes): lights left to the continuation
    (MODE_CONTINUATION) take no sample (glasslight.transmitted_light); None: every light.
    reflection: the caller weighs the samples by the reflective lobes and cuts each
    light's by lobe_cut (directlight.direct_light's light_cut): a delta light with only
    its glossy visibility on is sampled too, and every light with a cut is traced (the
    cut is applied per shadow ray); with many lights those lamps (glossy_only_lights)
    take entries of their own after the tree's (the sampler's ("light-glossy", li, si))."""
    chosen = selector_for(ctx, skip_mesh_lights)
    samples = []
    if chosen is not None:
        # Many lights: each shadow ray goes to one light the light tree picks per hit.
        S = selection_samples(ctx.settings)
        for si in range(S):
            if sampler is not None:
                # The light's point: scrambled, as each light's below.
                u1, u2 = sampler.uv(("light", 0, si))
                # The tree's choice stratified over the pixel's samples: the 2-D cell
                # read as one of m^2 strata in 1-D. Scrambled: with the linear cell
                # shift its pairing with the pixel jitter and the light's point was the
                # same in every pixel and seed, a bias no seed averaged away (a diffuse
                # floor under 200 small area lights: +0.49 % against every light
                # sampled, 18 standard errors over 6 seeds at 16 spp; now -0.03 %).
                c1, c2 = sampler.uv(("light-select", si))
                choose = np.minimum((np.floor(c2 * sampler.m) + c1) / sampler.m, ONE_BELOW)
            else:
                u1, u2, choose = rng.random((3, n))  # one draw: the same numbers
            samples.append((-1, True, S, u1, u2, choose))
        if reflection:
            # The lamps only the glossy lobes see, by shadow rays of their own (none of
            # the tree's members), cut per shadow ray (lobe_cut), after the tree's.
            for li in glossy_only_lights(ctx):
                count = ctx.plan.light_samples.get(ctx.lights[li].name, 1)
                for si in range(count):
                    if sampler is not None:
                        u1, u2 = sampler.uv(("light-glossy", li, si))
                    else:
                        u1, u2 = rng.random((2, n))
                    samples.append((li, True, count, u1, u2, None))
        return samples
    # Random numbers in the order the lights draw them (engine/lights/: u1, u2, then a
    # mesh light's triangle choice), sample by sample.
    plan = ctx.plan
    reflection_only = reflection_only_lights(ctx) if reflection else None
    for li, light in enumerate(ctx.lights):
        if skip_mesh_lights and light.kind == MESH:
            continue
        cut = lobe_cut(light) if reflection else 0
        if not light.ray_kinds & SHADOW and not (
                cut == CUT_DIFFUSE and (not light.has_size or reflection_only[li])):
            # The light object's diffuse visibility is off (a lamp that only highlights):
            # sampled for the glossy lobes alone (reflection_only_lights), else left to
            # the glossy continuation.
            continue
        if not light.shadow_sampled:  # Emission Sampling None on every emissive triangle
            continue
        if modes is not None and modes[li] == MODE_CONTINUATION:
            continue
        count = plan.light_samples.get(light.name, 1)
        traced = plan.shadows.get(light.name, True) or cut != 0
        for si in range(count):
            if sampler is not None and light.needs_choice:
                # A mesh light's triangle, an environment-mapped world's strategy: the
                # choice stratified with the point (directlight.sample_lights)
                u1, u2, sel = mesh_light_numbers(sampler, ("light", li, si))
                samples.append((li, traced, count, u1, u2, sel))
                continue
            sel = None
            if sampler is not None:
                # Scrambled cells: a light's point and the pixel jitter enter one product
                # (the lobe's value at the hit toward the point), and with the linear
                # shift their pairing within a pixel was the same in every seed, a bias no
                # seed averaged away (a close-up Principled ball of roughness 0.2, direct
                # pass: linear / scrambled 0.9935 at 64 spp, -10 standard errors over 100
                # seeds, paired; docs/performance.md "glossy02").
                u1, u2 = sampler.uv(("light", li, si))
                sel = rng.random(n) if light.needs_choice else None
            elif light.needs_choice:
                u1, u2, sel = rng.random((3, n))  # one draw: u1, u2, sel in this order
            else:
                u1, u2 = rng.random((2, n))
            samples.append((li, traced, count, u1, u2, sel))
    return samples


def mesh_light_numbers(sampler, key):
    """(u1, u2, triangle choice), each (N,), of a mesh light's shadow samples from the
    sampler's 2-D dimension `key`, stratified over the pixel's samples both ways: the
    cells (StratifiedSampler, m x m) spread the points (u1, u2) over the square, and the
    choice x = (m col + (row + s) mod m + jitter1) / m^2 of the sample in cell (col, row)
    lies in the cell's column, at one of its m sub-columns; with s (0..m-1) a hash of pixel,
    dimension, seed and column, the m samples of a column take distinct sub-columns, so
    the choices fill all m^2 strata of [0, 1) (multi-jittered sampling: Chiu, Shirley and
    Wang 1994; Kensler 2013, "Correlated multi-jittered sampling"). directlight.sample_lights
    picks the triangle by x and its CDF, rescales x within the triangle's CDF bin for the
    point's first coordinate and takes u2 for the second. Over pixels and seeds s is
    uniform whatever the cell and the jitters, so each sample's (x, u2) is uniform on the
    square and the estimate unbiased; the pixel's samples spread over the triangles in
    proportion to their power and over each triangle in two dimensions. (Measured,
    tests/test_mesh_light_stratified.py: a one-quad panel's pixel noise 0.27-0.53x, an
    18-triangle panel's 0.51-0.63x that of a triangle chosen by its own random number;
    one shift s for all columns: 0.28-0.61x, and tests/test_furnace.py's emitting box
    scattered more over seeds.) Samples beyond the pixel's whole rounds of cells keep
    x = u1. The cells are visited in the scrambled order: in the plain one their pairing
    with the pixel jitter repeats along image rows and columns, so pixels along a seam of
    the emitting box rose and fell together (a 1-D choice so stratified: its direct pass's
    image mean scattered 1.8x as widely over seeds)."""
    u1, u2 = sampler.uv(key)
    m = sampler.m
    if m < 2:
        return u1, u2, u1
    col = np.floor(u1 * m)
    # s: a splitmix64 finaliser of (pixel, dimension, seed), then of that and the column
    # (other constants than the sampler's cell shift)
    salt = (sampler.dims[key] * 0x9E3779B97F4A7C15 + sampler.salt * 0xBF58476D1CE4E5B9
            + 0x632BE59BD9B4E019) % (1 << 64)
    with np.errstate(over="ignore"):
        h = _mix64(np.asarray(sampler.pix).astype(np.uint64) * np.uint64(0xD1B54A32D192ED03)
                   + np.uint64(salt))
        h = _mix64(h ^ (col.astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15)))
    s = (h % np.uint64(m)).astype(np.int64)
    row = np.floor(u2 * m).astype(np.int64)
    jitter = np.clip(u1 * m - col, 0.0, ONE_BELOW)
    choice = np.minimum((col * m + (row + s) % m + jitter) / (m * m), ONE_BELOW)
    rest = np.asarray(sampler.sub) >= sampler.full
    choice[rest] = u1[rest]
    return u1, u2, choice


def _mix64(h):
    """splitmix64's finaliser of uint64 array h (wrapping arithmetic)."""
    with np.errstate(over="ignore"):
        h = h ^ (h >> np.uint64(30))
        h = h * np.uint64(0xBF58476D1CE4E5B9)
        h = h ^ (h >> np.uint64(27))
        h = h * np.uint64(0x94D049BB133111EB)
        return h ^ (h >> np.uint64(31))


MODE_CONTINUATION, MODE_DELTA, MODE_MIS, MODE_TREE = 0, 1, 2, 3

# Lamps with a size whose Diffuse visibility is off take shadow rays for the rough
# reflective lobes, MIS-weighted against the glossy continuation (reflection_only_lights;
# docs/accuracy.md "lampvis51"); False: the glossy continuation alone finds them, as
# before (the same mean at ~200x Cycles' pixel variance a sample in their highlight).
REFLECTION_ONLY_SAMPLING = True


def reflection_only_lights(ctx) -> np.ndarray:
    """(L,) bool: the lights with a size (area, sun with an angle, point / spot with a
    radius) whose Diffuse ray visibility is off and Glossy on (lobe_cut CUT_DIFFUSE), which
    the rough reflective lobes sample by shadow rays with that cut (direct_irradiance's
    reflection: light_sample_list, light_modes(ctx, reflection=True)), as Cycles' next-event
    estimation does for the closures SHADER_EXCLUDE_DIFFUSE leaves
    (intern/cycles/kernel/integrator/shade_surface.h, surface_shader.h
    _surface_shader_exclude). The continuation's glossy rays that meet such a lamp are
    then MIS-weighted against those samples (lamp_mis); its other rays (a rough glass's
    refraction, a translucent lobe's: engine/glasslight.py takes no sample of a lamp
    without diffuse visibility) count it in full, as before. With the light tree (its
    members are the lights with diffuse visibility: such a lamp is none) they take shadow
    rays of their own beside the tree's (glossy_only_lights). All False with
    REFLECTION_ONLY_SAMPLING off."""
    out = np.zeros(len(ctx.lights), np.bool_)
    if not REFLECTION_ONLY_SAMPLING:
        return out
    for li, light in enumerate(ctx.lights):
        out[li] = (light.has_size and light.shadow_sampled
                   and lobe_cut(light) == CUT_DIFFUSE
                   and light.kind in (AREA, SUN, POINT, SPOT))
    return out


def glossy_only_lights(ctx) -> list:
    """Indices of the lights the rough reflective lobes sample with the diffuse lobe cut
    (light_sample_list's reflection): a delta lamp whose Diffuse visibility is off and
    Glossy on, and the reflection-only lamps with a size (reflection_only_lights). With
    the light tree they are none of its members: they take shadow rays of their own
    beside the tree's pick (before, a delta one gave no highlight at all there)."""
    refl = reflection_only_lights(ctx)
    return [li for li, light in enumerate(ctx.lights)
            if light.shadow_sampled and lobe_cut(light) == CUT_DIFFUSE
            and (not light.has_size or refl[li])]


def lamp_mis(modes, reflection_only, li, ray_cls):
    """Which continuation rays that met light li take the MIS weight against its shadow
    rays: True (all: modes[li] MODE_MIS), an (N,) bool of the rays (a reflection-only lamp,
    reflection_only_lights: the glossy rays, ray_cls GLOSSY) or False (none)."""
    if modes[li] == MODE_MIS:
        return True  # (Python bools: callers test `is True` / `is False`)
    if reflection_only[li]:
        return np.asarray(ray_cls) == GLOSSY
    return False


def light_modes(ctx, reflection=False) -> np.ndarray:
    """How each light reaches the rough reflective lobes (directlight.accumulate_bsdf):
    MODE_DELTA: a point, spot or sun without size, by shadow rays only; MODE_MIS: an area
    light (with or without spread), a sun with an angle, a point / spot light with a
    radius, the emissive meshes and an environment-mapped world, by shadow rays and by
    the lobes' sampled continuation, the two weighted by the power heuristic (Veach;
    mis_light_pdf and _mesh_mis_weight give the light's pdf where a continuation meets
    it); MODE_CONTINUATION: a constant-colour world (its radiance is the same in every
    direction, so the lobes' own sampling follows f cos alone and is the better strategy:
    measured, its shadow rays' share doubled a rough metal's noise) and a light whose
    shadow rays are off (diffuse visibility), by the continuation alone.
    Without continuation (specular effects off) the MIS lights take shadow rays in full.
    The same with more lights than the light tree's threshold (the tree picks one light
    per shadow ray, MODE_TREE in the kernel): the light pdf of a MIS light then includes
    the tree's probability of choosing it at the point and shading normal the
    continuation left (LightSelector.pmf; Cycles' light_tree_pdf, pbrt-v4's
    BVHLightSampler::PMF), in the kernel (directlight.sample_lights) and in _mis_weight /
    _mesh_mis_weight alike.
    reflection: the modes the rough reflective lobes' shadow rays take (direct_irradiance
    with bsdf): the reflection-only lamps (reflection_only_lights) MODE_MIS too (MODE_DELTA
    without continuation); elsewhere they stay MODE_CONTINUATION (lamp_mis)."""
    modes = np.zeros(len(ctx.lights), np.int64)
    mis = MODE_MIS if ctx.plan.specular_depth > 0 else MODE_DELTA
    if reflection:
        modes[reflection_only_lights(ctx)] = mis
    for li, light in enumerate(ctx.lights):
        # A delta lamp seen by glossy rays but not diffuse ones is sampled for the glossy
        # lobes (light_sample_list's reflection), in full: no continuation meets it.
        glossy_only = lobe_cut(light) == CUT_DIFFUSE and not light.has_size
        if not (light.ray_kinds & SHADOW or glossy_only) or not light.shadow_sampled:
            continue
        if not light.has_size:
            modes[li] = MODE_DELTA
        elif (light.kind in (AREA, SUN, POINT, SPOT, MESH)
              or (light.kind == WORLD and light.environment is not None)):
            modes[li] = mis
    return modes


def mis_light_pdf(light, o, d, t, ns=None, p=None):
    """Solid-angle pdf (N,) with which the light's shadow-ray samples (directlight.
    sample_lights) pick direction d from o, for continuation rays that met the light at
    distance t (sun, world: escaping rays; ns (N,3): the shading normals at o, around
    which the world's shadow rays are cosine-distributed, and a sphere light's from inside
    it; p (N,3): the shading points the rays left, where the world's light portals are
    seen from (WorldLight.pdf), o where None)."""
    if light.kind == SUN:
        return np.full(len(d), 1.0 / light.solid_angle)
    if light.kind == WORLD:
        return light.pdf(d, ns, o if p is None else p)
    if light.kind in (POINT, SPOT) and light.is_sphere:
        return sphere_light_pdf(light, o, d, ns)
    if light.kind in (POINT, SPOT):
        # Shadow rays sample the disk of the light's radius through its centre, facing the
        # shading point o (directlight.sample_lights): pdf of the direction's disk point.
        axis = o - light.pos
        axis /= np.maximum(np.linalg.norm(axis, axis=1), 1e-300)[:, None]
        toward = -dot(d, axis)  # cosine at the disk
        front = toward > 1e-12   # rays parallel to or leaving the disk cannot reach it
        t_disk = dot(o - light.pos, axis) / np.where(front, toward, 1.0)
        on_disk = t_disk[:, None] * d + o - light.pos
        inside = (front & (t_disk > 0)
                  & (np.einsum("ij,ij->i", on_disk, on_disk) <= light.radius ** 2))
        pdf = t_disk * t_disk / np.where(front, math.pi * light.radius ** 2 * toward, 1.0)
        return np.where(inside, pdf, 0.0)
    cos_l = np.abs(dot(d, light.dir))
    area = light.area
    if light.kind == AREA and light._spread_rect():
        # A rectangle with spread samples only the part of it whose directions can reach
        # o (the square of half-width height x tan(spread / 2) around o's foot, clipped
        # to the light; Cycles' area_light_spread_clamp_light): uniform over that part.
        r = o - light.pos
        reach = np.maximum(dot(r, light.dir), 0.0) * math.tan(0.5 * light.spread)
        pu, pv = dot(r, light.u), dot(r, light.v)
        hx, hy = 0.5 * light.size_x, 0.5 * light.size_y
        x0, x1 = np.maximum(pu - reach, -hx), np.minimum(pu + reach, hx)
        y0, y1 = np.maximum(pv - reach, -hy), np.minimum(pv + reach, hy)
        area = np.maximum(x1 - x0, 0.0) * np.maximum(y1 - y0, 0.0)
        y = o + t[:, None] * d - light.pos
        yu, yv = dot(y, light.u), dot(y, light.v)
        inside = (yu >= x0) & (yu <= x1) & (yv >= y0) & (yv <= y1) & (area > 0)
        with np.errstate(over="ignore", invalid="ignore"):  # rows that missed: t = inf
            return np.where(inside, t * t / np.maximum(cos_l * area, 1e-300), 0.0)
    by_area = t * t / np.maximum(cos_l * area, 1e-300)
    if light.kind == AREA and light.shape != DISK:
        # A rectangle's shadow rays sample its solid angle where it is large enough
        # (directlight.sample_lights, lights/area.py): pdf 1 / omega there.
        ex = np.asarray(light.du, np.float64) * float(light.size_x)
        ey = np.asarray(light.dv, np.float64) * float(light.size_y)
        omega = np.empty(len(o))
        rect_solid_angles(np.ascontiguousarray(o, np.float64),
                          np.asarray(light.pos, np.float64) - 0.5 * (ex + ey), ex, ey, omega)
        solid = omega >= MIN_SPHERICAL_SOLID_ANGLE
        return np.where(solid, 1.0 / np.where(solid, omega, 1.0), by_area)
    return by_area


def _mesh_mis_weight(ctx, modes, prim, o, d, t, ng, pdf_b, p=None, ns=None, sets=None):
    """Power-heuristic weight (N,) of continuation rays that met emissive triangles prim
    (1 where the mesh light is not light-sampled with MIS or the lobe was mirror-like):
    the mesh light's shadow rays pick a triangle by its triangle tree's probability at the
    point and shading normal they leave (MeshLight.triangle_pmf), then a uniform point
    (pdf pmf / area x t^2 / |cos|) or, for a triangle large against its distance, a
    direction uniform in its solid angle (pmf / omega): MeshLight.shadow_pdf, as
    directlight.sample_lights. With the light
    tree (p, ns (N,3): the points and shading normals the rays left) that pdf takes the
    tree's probability of choosing the mesh light there (LightSelector.pmf; sets (N,):
    the receiver sets of the surfaces the rays left, whose own trees pick there:
    lightlinking.tree_pmf)."""
    w = np.ones(len(prim))
    chosen = selector_for(ctx)
    for li, light in enumerate(ctx.lights):
        if light.kind != MESH or modes[li] != MODE_MIS:
            continue
        k = _mesh_rows(ctx, light, prim)
        rows = np.nonzero((k >= 0) & np.isfinite(pdf_b))[0]
        if not len(rows):
            continue
        kk = k[rows]
        cos_l = np.abs(dot(d[rows], ng[rows]))
        at = (o if p is None else p)[rows]
        if chosen is not None:
            count = selection_samples(ctx.settings) * tree_pmf(
                ctx, chosen, at, ns[rows], li, None if sets is None else sets[rows])
        else:
            count = ctx.plan.light_samples.get(light.name, 1)
        pl = count * light.shadow_pdf(at, ns[rows], kk, t[rows], cos_l)
        pb = pdf_b[rows]
        w[rows] = pb * pb / np.maximum(pb * pb + pl * pl, 1e-300)
        # A side shadow rays do not sample (Emission Sampling): its light counts in full.
        free = light.unsampled_side(kk, d[rows])
        if free.any():
            w[rows[free]] = 1.0
    return w


def _mesh_rows(ctx, light, prim):
    """Rows (N,) of the mesh light's triangles (v0 ...) for scene triangles prim (N,) int,
    -1 where a triangle is not one of them (a lookup over the scene's triangles, built
    once per light)."""
    lookup = getattr(light, "_tri_lookup", None)
    if lookup is None or len(lookup) != ctx.geo.count:
        lookup = np.full(ctx.geo.count, -1, np.int64)
        lookup[light.tri_index] = np.arange(len(light.tri_index))
        light._tri_lookup = lookup
    return lookup[prim]


def _unsampled_meshes(ctx) -> list:
    """The mesh lights with a side shadow rays do not sample (Emission Sampling None,
    Front or Back; MeshLight.sides), whose light there diffuse surfaces receive through
    the gather rays that meet it (unsampled_emission)."""
    return [light for light in ctx.lights if light.kind == MESH
            and light.tri_sides is not None and (light.sides() != 3).any()]


def unsampled_emission(ctx, meshes, prim, d, Le):
    """Le (N,3) where rays of direction d (N,3) met emissive triangles prim (N,) on a side
    the shadow rays do not sample (MeshLight.unsampled_side), 0 elsewhere: the light of
    those sides reaches a diffuse surface by its gather rays alone, counted in full (as
    Cycles' shade_surface counts a BSDF hit on an emitter without MIS for that side), so
    a surface lit by an emitter of Emission Sampling None is as bright as with Front and
    Back (tests/test_emission_sampling.py)."""
    out = np.zeros_like(Le)
    for light in meshes:
        k = _mesh_rows(ctx, light, prim)
        rows = np.nonzero(k >= 0)[0]
        if not len(rows):
            continue
        free = rows[light.unsampled_side(k[rows], d[rows])]
        out[free] = Le[free]
    return out


def _mis_weight(ctx, li, light, o, d, t, pdf_b, ns=None, p=None, sets=None):
    """Power-heuristic weight of continuation rays (pdf pdf_b, inf = a mirror-like lobe)
    that met light li, against its light_samples shadow rays (ns: the shading normals at
    the rays' origins, for the world light). With the light tree (p, ns: the hit points
    and shading normals the rays left) the shadow rays' pdf includes the probability
    that the tree picks light li there (LightSelector.pmf; sets (N,): the receiver sets
    of the surfaces the rays left, whose own trees pick there: lightlinking.tree_pmf)."""
    chosen = selector_for(ctx)
    if chosen is not None and not light.ray_kinds & SHADOW:
        chosen = None  # (a lamp only glossy rays see: its own shadow rays, no tree pick)
    with np.errstate(invalid="ignore", over="ignore"):  # rows that missed it: t = inf
        if chosen is not None:
            n = selection_samples(ctx.settings)
            pl = n * mis_light_pdf(light, o, d, t, ns, p) * tree_pmf(
                ctx, chosen, o if p is None else p, ns, li, sets)
        else:
            n = ctx.plan.light_samples.get(light.name, 1)
            pl = n * mis_light_pdf(light, o, d, t, ns, p)
        w = pdf_b * pdf_b / (pdf_b * pdf_b + pl * pl)
    return np.where(np.isinf(pdf_b), 1.0, np.nan_to_num(w, nan=1.0))


def first_at_each_distance(met):
    """The lamps met (a list of (light index, light, rows (k,) int64, distances (k,),
    per-row arrays ...) per lamp, in light order) without a ray's second lamp at the
    distance of one before it: Cycles' main path meets only the first of lamps at one
    distance (lights_intersect keeps a lamp only nearer than the hit so far, `t >=
    isect->t` skipped, in light order) and goes on from past that distance (shade_light:
    tmin = intersection_t_offset(t), the next hit needs t > tmin), so the others there
    are neither seen nor counted as passes (a lamp duplicated in place). Entries left
    with no row are dropped; the rest keep their order and per-row arrays."""
    if len(met) < 2:
        return met
    sizes = [len(entry[2]) for entry in met]
    rows = np.concatenate([entry[2] for entry in met])
    dist = np.concatenate([entry[3] for entry in met])
    order = np.lexsort((np.repeat(np.arange(len(met)), sizes), dist, rows))
    r, t = rows[order], dist[order]
    tie = np.zeros(len(order), bool)
    tie[1:] = (r[1:] == r[:-1]) & (t[1:] == t[:-1])
    if not tie.any():
        return met
    drop = np.zeros(len(order), bool)
    drop[order[tie]] = True
    out, start = [], 0
    for entry, k in zip(met, sizes):
        keep = ~drop[start:start + k]
        start += k
        if keep.all():
            out.append(entry)
        elif keep.any():
            out.append(tuple(entry[:2]) + tuple(np.asarray(x)[keep] for x in entry[2:]))
    return out


def lamp_passes(met, n, t_count, t_limit):
    """The camera paths' passes through the lamps their rays met (met: a list of (light
    index, light, rows (k,) int64, distances (k,), ...) per lamp), as Cycles counts them:
    each a transparent bounce (integrator_shade_light_forward), the path ending at the
    lamp whose pass brings its count (t_count (n,) int64, the passes so far) to t_limit
    (Max Bounces > Transparent). Returns (t_end (n,): where each path ends, at that
    lamp, inf for the paths that go on; None when none ends there, the counts (n,) after
    the passes counted up to that lamp)."""
    met_count = np.zeros(n, np.int64)
    for entry in met:
        met_count[entry[2]] += 1
    total = t_count + met_count
    over = np.flatnonzero((total >= t_limit) & (met_count > 0))
    if not len(over):
        return None, total
    # The pass that reaches the limit: the (t_limit - t_count)-th nearest lamp met.
    rows = np.concatenate([entry[2] for entry in met])
    dist = np.concatenate([entry[3] for entry in met])
    take = np.isin(rows, over)
    rows, dist = rows[take], dist[take]
    order = np.lexsort((dist, rows))
    rows, dist = rows[order], dist[order]
    start = np.searchsorted(rows, over)
    nth = np.maximum(t_limit - t_count[over], 1) - 1
    t_end = np.full(n, np.inf)
    t_end[over] = dist[start + nth]
    total[over] = np.maximum(t_limit, t_count[over])
    return t_end, total


def lamps_met(ctx, o, d, t, cls, link_prim=None, exempt=None):
    """The lamps with a surface that the rays o, d (N,3) of classes cls ((N,) int64 or a
    scalar; a lamp is seen by the classes of its Light.ray_kinds) meet before t (N,)
    (inf: anywhere), as Cycles' main path meets them (light.h lights_intersect_impl:
    with Light Linking a ray that left a surface skips a lamp with Shadow Linking, left
    to the dedicated shadow-linking ray, and a lamp that does not light that surface,
    both before its nearest-hit test): link_prim (N,) int64, the triangle each ray left
    (-1: the camera), with ctx.links; None: no Light Linking here. exempt (N,) bool or
    scalar: the rays to which neither applies (camera rays and their transparent
    continuations, Cycles' PATH_RAY_CAMERA); None: none. Returns (met, linked): met,
    first_at_each_distance of the (light index, light, rows (k,) int64, distances (k,),
    L (k,3)) per lamp met, in light order (lamp_passes counts them); linked, the
    shadow-linked lamps' (light index, light, rows, distances (N,), L) past their
    blockers (shadow_linked_rows; no passes)."""
    met, linked = [], []
    links = ctx.links if link_prim is not None else None
    for li, light in enumerate(ctx.lights):
        if not light.has_surface:  # nothing to meet (many point lights: no cost)
            continue
        sees = (cls & light.ray_kinds) != 0
        if not np.any(sees):
            continue
        past = links.blocker_accel(li) if links is not None else None
        if past is not None:
            # Shadow Linking: a ray that left a surface meets this lamp past its
            # non-blockers (Cycles' dedicated shadow-linking ray), the path going on to
            # its own hit.
            got = shadow_linked_rows(ctx, li, light, past, o, d,
                                     sees if exempt is None else sees & ~exempt, link_prim)
            if got is not None:
                linked.append((li, light) + got)
            if exempt is None:
                continue
            sees = sees & exempt
            if not sees.any():
                continue
        mask, tl, L = light.intersect(o, d, t)
        if L is not None and mask.any():
            mask &= sees
            if links is not None:
                # Seen from a surface the lamp does not light: not its light.
                hit = links.lights_hit(li, ctx.geo, link_prim)
                mask &= hit if exempt is None else exempt | hit
            rows = np.nonzero(mask)[0]
            if len(rows):
                met.append((li, light, rows, np.take(tl, rows), L[rows]))
    return first_at_each_distance(met), linked


def shadow_linked_rows(ctx, li, light, past, o, d, sees, link_prim):
    """The rays o, d (N,3) that meet lamp li, whose shadows only its blockers cast (past:
    their lightlinking.BlockerAccel), wherever it lies (Cycles' dedicated shadow-linking
    ray, intersect_dedicated_light.h): those of sees ((N,) bool or scalar) whose surface
    left (link_prim (N,) int64) the lamp lights (links.lights_hit) with no blocker
    between. Returns None (none) or (rows (k,) int64, distances (N,) inf where missed,
    L (k,3) the lamp's radiance)."""
    mask, tl, L = light.intersect(o, d, np.full(len(o), np.inf))
    if L is None or not mask.any():
        return None
    mask &= sees & ctx.links.lights_hit(li, ctx.geo, link_prim)
    rows = np.nonzero(mask)[0]
    if not len(rows):
        return None
    o32 = np.ascontiguousarray(o[rows], np.float32)
    d32 = np.ascontiguousarray(d[rows], np.float32)
    t32 = np.ascontiguousarray(tl[rows] * (1.0 - 1e-5), np.float32)
    blocked = np.zeros(len(rows), np.bool_)
    past.occluded_into(o32, d32, t32, blocked)
    keep = ~blocked
    rows, L = rows[keep], L[rows][keep]
    if not len(rows):
        return None
    return rows, tl, L


def _add_lamp_light(ctx, li, light, rows, L, o, d, tl, mis, passages, pdf_b, org_ns, org_p,
                    link_prim, lamp_w, clamping, tp, chain, s, acc, target, pix, ftp, feat,
                    clamp_tp=None):
    """The light L (K,3) of lamp li that the rays at rows met (at tl along o, d) into the
    accumulator: weighted by MIS against the BSDF rays' pdf_b when `mis` (the light tree's
    choice in the receiver sets of link_prim; an (N,) bool array: for those rays,
    lamp_mis), by the shade the path left (lamp_w),
    clamped, and into the data passes. clamp_tp: (N,3) the throughput the clamp reads
    (sampleclamp.split_throughput; None: tp)."""
    per_ray = None
    if isinstance(mis, np.ndarray):
        # (lamp_mis: the rays that take the weight, the others count the lamp in full)
        per_ray = np.take(np.broadcast_to(mis, (len(o),)), rows)
        mis = bool(per_ray.any())
    if mis:
        om, tm = o[rows], tl[rows]
        if passages is not None:
            om, tm = passages.mis_origin(rows, om, d[rows], tm, org_p[rows])
        w = _mis_weight(ctx, li, light, om, d[rows], tm, pdf_b[rows], org_ns[rows],
                        org_p[rows], _link_sets(ctx, link_prim, rows))
        if per_ray is not None:
            w = np.where(per_ray, w, 1.0)
        L = L * w[:, None]
    if lamp_w is not None and len(rows):
        # Its light through the shade the path left: shared with the shade samples of
        # the glossy hit before (shadelight.shade_bsdf_weights).
        L = L * lamp_w[rows, li][:, None]
    if clamping:
        L = sampleclamp.clamp(L, tp if clamp_tp is None else clamp_tp, rows,
                              sampleclamp.bounce_limits(s, np.take(chain[:, 0], rows) - 1))
    acc.add(target, pix, L, tp, rows)
    datapasses.add_light(acc, pix, rows, tp, ftp, feat, L)
    if acc.light is not None:
        acc.light.met(pix, L, tp, rows, lightpasses.EMISSION)


def _shadow_linked_suns(ctx, links, o, d, rows_mask, link_prim, modes, pdf_b, org_ns, org_p,
                        clamping, tp, chain, acc, target, pix, ftp, feat, s, clamp_tp=None,
                        refl_only=None, ray_cls=None):
    """Shadow Linking for lights at infinity (suns): the rays rows_mask (n,) that met a
    surface see a shadow-linked sun's disc when no blocker of it lies in that direction
    (its BlockerAccel; Cycles' dedicated shadow-linking ray counts distant lights),
    weighted as the discs the missing rays see (MIS, clamping; clamp_tp:
    _add_lamp_light's; refl_only, ray_cls (n,): lamp_mis's, None: by modes alone)."""
    for li, light in enumerate(ctx.lights):
        past = links.blocker_accel(li)
        if past is None or not hasattr(light, "seen_at_infinity"):
            continue
        rows = np.nonzero(rows_mask & links.lights_hit(li, ctx.geo, link_prim))[0]
        if not len(rows):
            continue
        sun = light.seen_at_infinity(d[rows])
        if sun is None:
            continue
        lit = np.any(sun > 0, axis=1)
        rows, sun = rows[lit], sun[lit]
        if not len(rows):
            continue
        blocked = np.zeros(len(rows), np.bool_)
        past.occluded_into(np.ascontiguousarray(o[rows], np.float32),
                           np.ascontiguousarray(d[rows], np.float32),
                           np.full(len(rows), np.finfo(np.float32).max, np.float32), blocked)
        rows, sun = rows[~blocked], sun[~blocked]
        if not len(rows):
            continue
        mis = (bool(modes[li] == MODE_MIS) if refl_only is None
               else lamp_mis(modes, refl_only, li, ray_cls))
        if mis is not False:
            w = _mis_weight(ctx, li, light, o[rows], d[rows], None, pdf_b[rows],
                            org_ns[rows], org_p[rows], _link_sets(ctx, link_prim, rows))
            if mis is not True:  # (the glossy rays alone)
                w = np.where(np.take(np.broadcast_to(mis, (len(o),)), rows), w, 1.0)
            sun = sun * w[:, None]
        if clamping:
            sun = sampleclamp.clamp(sun, tp if clamp_tp is None else clamp_tp, rows,
                                    sampleclamp.bounce_limits(
                                        s, np.take(chain[:, 0], rows) - 1))
        acc.add(target, pix, sun, tp, rows)
        datapasses.add_light(acc, pix, rows, tp, ftp, feat, sun)
        if acc.light is not None:
            acc.light.met(pix, sun, tp, rows, lightpasses.EMISSION)


def _linked_emission(ctx, Le, prim, from_prim, idx):
    """Le (n,3) of the emitting triangles prim that gather rays met, without what an
    emitting object with links of its own does not give the surfaces the rays left
    (from_prim at idx; Light Linking, lightlinking.LightLinks.emission_lights)."""
    links = getattr(ctx, "links", None)
    if links is None or not links.has_emitters or not np.any(Le > 0):
        return Le
    return Le * links.emission_lights(ctx.geo, prim, np.take(from_prim, idx))[:, None]


def _link_sets(ctx, link_prim, rows=None):
    """Light Linking: the receiver sets (n,) of the surfaces the rays at rows (None: all)
    last left (link_prim), for tree_pmf; None without linking."""
    if link_prim is None:
        return None
    prim = link_prim if rows is None else np.take(link_prim, rows)
    return ctx.links.receiver_set(ctx.geo, prim)


def light_shadow_rays(ctx, hit, light_index, rng):
    """One sample of light ctx.lights[light_index] per hit, as the kernels make it:
    (rows (M,) of the lit hits, irradiance without visibility (M,3), float32 shadow-ray
    origins (M,3), directions (M,3), tmax (M,)). For tests and diagnostics."""
    n = len(hit.p)
    light = ctx.lights[light_index]
    u1, u2 = rng.random(n), rng.random(n)
    sel = rng.random(n) if light.needs_choice else None
    buf = DirectLightBuffers().ensure(max(n, 1))
    codes, params, mesh = pack_lights(ctx.lights)
    m_all, m_rays = sample_lights(*_hit_arrays(ctx.geo, hit), codes, params, *mesh,
                                  *empty_tree(), np.ones(len(codes), np.bool_),
                                  np.array([light_index], np.int64), np.ones(1, np.bool_),
                                  u1[None], u2[None],
                                  np.zeros((1, 1)) if sel is None else sel[None],
                                  buf.contrib, buf.row, buf.kidx, buf.ray, buf.o32, buf.d32,
                                  buf.t32, buf.wdir, buf.lpdf, buf.bump, NO_HROWS, NO_ROWS3)
    return (buf.row[:m_all].copy(), buf.contrib[:m_all].copy(), buf.o32[:m_rays].copy(),
            buf.d32[:m_rays].copy(), buf.t32[:m_rays].copy())


def _hit_arrays(geo, hit, rows=None):
    """The per-hit inputs of directlight.sample_lights (computed once per batch, not per
    light sample): points, normals, the lit-side normal, origin offsets, Cycles' shading
    offset, the shadow-terminator cut-off and smooth-surface lift of smooth triangles, and
    the smooth normals before Normal Map / Bump nodes (Cycles' bump shadowing term).
    An offset no object has is an empty array (sample_lights reads no rows).
    rows (K,) int64: only these hits are sampled (direct_irradiance's rows): the
    terminator rows are computed for them alone (the rest stay unwritten and unread)."""
    n = len(hit.p)
    c = np.ascontiguousarray
    # Per-object offsets: where no object has one (bitwise zero), no per-hit rows to read.
    shading_offset = (np.take(geo.terminator_shading, hit.prim)
                      if n and geo.object_terminator_shading.view(np.uint32).any()
                      else NO_ROWS)
    cutoff = NO_ROWS
    lift = NO_ROWS3
    # terminator_lift leaves cutoff and lift 0 unless an object's offset is > 0.
    if hit.bary is not None and n and (geo.object_terminator > 0).any():
        cutoff = np.empty(n)  # (every row written)
        lift = np.empty((n, 3))
        tri, (smooth, object_id, v0, e1, e2, normals) = geo.hit_tables(
            hit.prim, "smooth", "object_id", "v0", "e1", "e2", "corner_normals")
        terminator_lift(tri, c(hit.bary, np.float64), c(hit.ng, np.float64), smooth,
                        object_id, geo.object_terminator, v0, e1, e2, normals, cutoff, lift,
                        NO_HROWS if rows is None else c(rows, np.int64))
    ns = c(hit.ns, np.float64)
    n_smooth = getattr(hit, "n_smooth", None)
    # The normal whose hemisphere decides which light directions a hit can receive is
    # chosen in the kernel (gate NO_ROWS3): the geometric normal, except on smooth-shaded
    # triangles with a shadow terminator offset (cut-off > 0), where (as in Cycles) light
    # the shading normal faces is traced even when it arrives just below the flat facet:
    # its shadow ray leaves from the smooth surface (directlight.terminator_lift) and is
    # shadowed only if it really meets geometry, the facet itself included (Cycles skips
    # the own triangle only when NgL > 0).
    return (c(hit.p, np.float64), ns, NO_ROWS3,
            c(hit.ng, np.float64), c(hit.offset, np.float64),
            c(shading_offset, np.float64), cutoff, lift,
            ns if n_smooth is None else c(n_smooth, np.float64))


_UNSET = object()  # gather_indirect's lean: not given


# Gather rays that end near a corner or contact, where the precomputed irradiance is cut
# off and biased dark (or, closer than its resolution, could come from round the corner),
# gather once more from their end, up to this many levels deep (Jensen's advice for
# short gather rays). Deeper, the lookup is used as it is.
MAX_GATHER_LEVEL = 2
# Gather lookups whose counts drop some of their level map's photons read their usable
# photons alone at their gather point (_chain_lookups; gatherlevel44). False: the read
# before (the map whole below the reroute share, the last level's scaled by the whole
# map's kept share), kept as an A/B diagnostic (bench/bench_accuracy_ab.py
# --variant old:@integrator.LOOKUP_SUBSETS=False).
LOOKUP_SUBSETS = True
# Guided gather directions (engine/guiding.py) at the regathers' levels too (True), or at
# level 0 only
GUIDE_REGATHERS = False


def gather_indirect(ctx, hit, rng, counters: Counters, sampler=None, rays=None,
                    level=0, should_cancel=None, lean=_UNSET, extra=None,
                    glow_only=False, caustic=None, passes=None, d_pdf=None,
                    clamp=None, world=None) -> np.ndarray:
    """Indirect irradiance by final gathering: cosine-distributed rays; radiance where they
    (or their mirror / glass continuations) meet a diffuse surface comes from the
    precomputed photon irradiance. Mean radiance times pi = irradiance.
    level > 0: a recursive gather from a corner; it also counts the emission of the
    emissive meshes its rays hit (direct light there comes from shadow rays to the other
    lights only). lean: gatherkernels.lean_materials(ctx.table) if the caller has it (the
    recursion passes its own).
    Regathers: the lookups to gather again (a boundary or a short ray, levels below
    MAX_GATHER_LEVEL) over all G rays and all their continuations are collected and
    gathered in one batch at the end (_regather); their random numbers draw from a
    stream of their own (_spawn: the chunk's stream for the rays of this level is drawn
    as before).
    extra: (N,4) int64, the hits' bounces beyond this level's own (B_TOTAL order: a
    camera chain's mirror / glass / glossy / sheen bounces, engine/chaincounts.py; None:
    none). The gather rays' own continuations add theirs: a lookup past a limit adds
    nothing, and one whose counts drop more light than its level's map holds
    (chaincounts.GatherCounts.reroute) gathers again from its end; the others that drop
    some of its photons (every one at the last level) read their usable photons' alone
    at their gather point (chaincounts.subset_irradiance).
    glow_only: the irradiance from emitting media alone (engine/volumeemission.py): no
    lookup, no surface emission, no lamps' light scattered in fog; the glow's second
    bounce gathers that way from level 0's gather ends.
    caustic: (N,3) float64 zeros, level 0: receives (added in place) the irradiance the
    chains carry where Cycles' Filter Glossy blurs the caustic / glow maps' paths
    (engine/glossysplit.py), the maps' light at D; None: that goes into the result.
    passes: (N,) int64, the transparent bounces each hit's path made before it (the
    camera path's, Cycles' transparent_bounce; None: 0). The rays' chains go on counting
    from there (a transparent pass adds one, as path_state_next counts it along the
    whole path): a chain that reaches Light Paths > Max Bounces > Transparent ends at its
    next surface (its emission counted, no lookup, no continuation), and a regathered
    end's shadow rays and next gather start from its count (_gather_pass_counts).
    d_pdf: the hits' glossysplit.DiffusePdf at the split's Filter Glossy if the caller
    has it (_photon_terms: the same object, built once; None: built here when needed).
    clamp: (w (N,3), limit) at level 0: Cycles' Clamp Indirect held per gather ray, as
    Cycles clamps each path's contribution (engine/sampleclamp.py): ray g's irradiance
    E_g (its lookups, regathers and emission; its chain's light into caustic apart, a
    contribution of its own) scaled so that |w x G x E_g|_1 <= limit, w the camera path's
    clamp throughput x the gathering lobe's f (G x E_g x f: the radiance one path through
    the ray carries); the result sums the held E_g. None: no clamp (the caller's).
    world: (out (N,3) float64, scale (3,)) at level 0 (integrator.world_gather): each ray
    that leaves a hit and meets nothing adds its throughput x scale to out at its hit (the
    constant world's direct light, its balance-heuristic share beside the shadow rays';
    WORLD_GATHER_MIS), none of it to the result; None: the escaping rays add nothing."""
    n = len(hit.p)
    E = np.zeros((n, 3))
    lim = ctx.settings.bounce_limits
    if extra is None and (level + 1 > lim[0] or level + 1 > lim[1]):
        # This level's rays are a diffuse bounce past a limit: Cycles takes none (a
        # corner's subset map of no photon still flagged its boundaries, and Diffuse 1
        # regathered twice: direct light after two diffuse bounces).
        return E
    pending = []  # the regathers' (target row, tp, wd, prim, u, v, d, extra, secondary,
    # passes, footprint, spread), per step
    G = rays or ctx.settings.gather_rays
    c = np.ascontiguousarray
    regather = level < MAX_GATHER_LEVEL
    sigma = media.absorption_table(ctx.table)  # absorbing media (NO_SIGMA: none)
    # The hits' fields as the kernel reads them, once for all G rays.
    ns, ng, p, offset = (c(a, np.float64) for a in (hit.ns, hit.ng, hit.p, hit.offset))
    # Plain diffuse materials: their hits skip the closures' set-up and the continuation
    # (gatherkernels.lean_diffuse; the same numbers, docs/performance.md "Eighth slice").
    if lean is _UNSET:
        lean = lean_materials(ctx.table)
    table_alpha = c(ctx.table.alpha, np.float64)
    # The map of this level's depth (bounce limits; None: no photon within them).
    gmap = None if glow_only else _deeper(ctx.gather_map, ctx.regather_maps, level)
    # This thread's arrays for this level's steps (a call of the next level, the
    # regathers', uses its own).
    buf = _gather_buffers(ctx, level)
    # Level 0: mesh lights whose unsampled sides its rays must count (level > 0 counts
    # every emitter it meets: its direct light skips the mesh lights).
    unsampled = _unsampled_meshes(ctx) if level == 0 and not glow_only else []
    # The rays that crossed only window glass and transparent passes, which count what a
    # first hit counts where they meet it (level 0: those sides; a regather level: every
    # emissive mesh; engine/gatherpassages.py; None: no surface shadow rays cross, or
    # nothing to count).
    passed = (GatherPassages.for_context(ctx, n) if n and not glow_only and (
        unsampled or (level > 0 and any(light.kind == MESH for light in ctx.lights)))
        else None)
    # Surfaces touching glass (engine/coincident.py; None: no glass touches anything):
    # per gathering hit, whether its rays may meet one where they leave (near) and
    # whether it is glass (its rays may be inside the glass), once for all G rays.
    coincident = CoincidentSurfaces.for_context(ctx)
    if coincident is not None:
        hit_prim = np.asarray(hit.prim, np.int64)
        near_h = coincident.near(p, hit_prim)
        glass_h = np.take(coincident.is_glass, hit_prim)
        from_h = np.empty(n, np.int64)  # the triangle each ray left, by hit row
    # Photon-guided directions (engine/guiding.py; setting gather_guiding): level 0 (the
    # regathers keep the cosine lobe unless GUIDE_REGATHERS). Each hit's tables, once for
    # its G rays.
    guide = (getattr(ctx.gather_map, "guide", None) if n and not glow_only
             and (level == 0 or GUIDE_REGATHERS) else None)
    if guide is not None:
        g_rows, g_cols = guide.tables(guide.points_for(p, ns))
    # The medium each ray is in, by hit row (a hit has one ray a step; -1: none known,
    # the back-face rule; engine/media.py). None: no absorbing material.
    medium_h = np.empty(n, np.int64) if sigma.shape[0] else None
    start_medium = None
    if medium_h is not None and getattr(hit, "medium", None) is not None:
        start_medium = np.where(np.asarray(hit.medium, np.int64)
                                == np.asarray(hit.mat, np.int64), -1,
                                np.asarray(hit.medium, np.int64))
    # Scattering media (engine/volumescatter.py; None: no material scatters).
    scatter = (volumewalk.WalkingScattering.for_context(ctx)
               if medium_h is not None and not glow_only else None)
    # A scattering world volume (engine/worldmedium.py): the rays' media outside the
    # objects' are its row, and the rays that escape scatter the lamps' light along
    # their whole length (their hits taken before the misses are compacted away).
    # (the camera paths' media already are its row outside the objects': hit.medium)
    world_row = worldmedium.medium_row(ctx)
    # Emitting media (engine/volumeemission.py; None: none emits): each ray's segment
    # in one adds its glow (the only way a surface sees it: Cycles samples no light
    # from volume emission either).
    glow = (volumeemission.MediumEmission.for_context(ctx) if medium_h is not None
            else None)
    fog_escapes = world_row >= 0 and (scatter is not None or glow is not None)
    # The glow's second bounce: emitting media send no photons (engine/volumeemission.py),
    # so level 0's gather ends gather the glow that lights them (one ray each, glow only;
    # without it a box glowing in a white corner left the walls at 0.64 of Cycles, with
    # it 0.85-0.89: docs/accuracy.md volemit38).
    second_glow = glow is not None and level == 0 and not glow_only
    # Smooth glass whose turned-normal reflections the photons cannot carry
    # (engine/turnedlight.py; None: none in this scene): the chains cross it by Cycles'
    # rule (no guard) and those that took one add the suns they escape into. turned_h:
    # per hit row, whether its ray's chain took one.
    turned_refl = None if glow_only else TurnedReflections.for_context(ctx)
    if turned_refl is not None:
        turned_h = np.zeros(n, bool)
    # Cycles' Filter Glossy on the chains (engine/glossysplit.py; None: off): level 0's
    # chains blur their lobes and add the light the caustic / glow maps leave out.
    fg_split = glossysplit.split_filter_glossy(ctx) if level == 0 and not glow_only else 0.0
    chains = (glossysplit.GatherChains(ctx, n, fg_split, d_pdf if d_pdf is not None
                                       else glossysplit.DiffusePdf(ctx, hit, fg_split))
              if fg_split > 0.0 else None)
    E_chain = E if caustic is None else caustic
    # Clamped per ray: each ray's shares go to rows of its own (E_rays[g], and the
    # regathers' targets g x n + row), summed after the clamp below.
    E_out, chain_out = E, caustic
    if clamp is not None:
        E_rays = np.zeros((G, n, 3))
        chain_rays = None if caustic is None else np.zeros((G, n, 3))
    # Each ray's transparent bounces by hit row (None: no surface or lamp a ray may
    # pass, or nothing to count), the limit and the volume-only surfaces (their pass is
    # none). The chains' lamps are passes (GatherChains.emission): counted on from step
    # to step, as a camera path counts them, where emission runs (continuation lights or
    # unsampled mesh sides; elsewhere a chain counts no lamp: mis51's known gap).
    t_limit, t_h, t_vol = _gather_pass_counts(
        ctx, n, passes, lamps=chains is not None
        and bool(chains.continuation_lights or chains.unsampled)
        and any(light.has_surface for light in ctx.lights))
    # The path's ray footprint at each ray's origin, by hit row (Cycles' dP: the hits', then
    # their chains' last vertex's), and its dD (the hits' spread): the ends' footprint for
    # Bump nodes (bump.transfer_footprint). None: the hits' is not known (the ends take the
    # geometry's view_footprint).
    fp_start = getattr(hit, "footprint", None)
    if fp_start is not None:
        fp_start = c(fp_start, np.float64)
        spread_h = (np.zeros(n) if getattr(hit, "spread", None) is None
                    else c(hit.spread, np.float64))  # (none known: no spread)
        fp_h = np.empty(n)
    for g in range(G):
        if clamp is not None:
            E = E_rays[g]
            E_chain = E if chain_rays is None else chain_rays[g]
        idx, o, d, tp = buf.rays(n)
        if fp_start is not None:
            fp_h[:] = fp_start
        # (rng.random(out=) draws the numbers rng.random((2, n)) draws, in place)
        # Scrambled cells: the direction and the pixel jitter enter one product (what the
        # ray sees from where the pixel's sample landed: edges, seams), and with the
        # linear shift their pairing within a pixel was the same in every seed, a bias
        # no seed averaged away (ball, floor and wall at 16 x 16 pixels, indirect pass:
        # linear / scrambled 1.0083 at 64 spp, +9 standard errors over 60 seeds, paired;
        # docs/performance.md "glossy02").
        u1, u2 = (sampler.uv(("gather", g)) if sampler is not None
                  else rng.random(out=buf.uv[:2 * n].reshape(2, n)))
        if guide is not None:
            # The mixture's (u1, u2) and each ray's weight cos / (pi pdf) = 1 / q.
            u1, u2, g_w = guide_warp(np.asarray(u1, np.float64), np.asarray(u2, np.float64),
                                     g_rows, g_cols)
        k = gather_rays(c(u1, np.float64), c(u2, np.float64), ns, ng, p, offset, idx, o, d)
        idx, o, d, tp = idx[:k], o[:k], d[:k], tp[:k]
        # The rays start at throughput 1. The buffer's rows stay ones between steps and
        # calls (the compactions move ones onto ones; the continuations' throughputs are
        # new arrays), so they are filled only past the rows known to be ones.
        if buf.tp_ones < k:
            tp.fill(1.0)
            buf.tp_ones = k
        if chains is not None:
            chains.start(idx, d, ns)
        if passed is not None:
            passed.start(idx)
        if guide is not None:
            tp *= np.take(g_w, idx)[:, None]
            buf.tp_ones = 0
        if getattr(hit, "n_smooth", None) is not None:
            # Bent normals: the diffuse lobe's sampled directions take Cycles' bump
            # shadowing term as its light samples do (engine/normalmap.py).
            tp *= bump_shadowing(hit.n_smooth[idx], hit.ns[idx], d)[:, None]
            buf.tp_ones = 0
        ray_cls = DIFFUSE  # then glossy / transmission after a specular bounce
        if turned_refl is not None:
            turned_h[:] = False
        if t_h is not None:
            t_h[:] = 0 if passes is None else passes
        if medium_h is not None:
            # From the gathering surface: the medium its camera path was in (a floor
            # inside a fog cube; not its own medium's surface), else not known.
            medium_h[idx] = (np.full(len(idx), world_row, np.int64)  # (-1: none)
                             if start_medium is None else np.take(start_medium, idx))
        # The bounces beyond the level's own of each hit's ray (a hit has one ray a step:
        # indexed by idx through the compactions; None: none yet).
        cnt = None if extra is None else np.array(extra, np.int64)
        cnt_in = cnt
        # The point (None: the gathering hits', p[idx]) and triangle each ray left, and
        # whether any may meet a touching surface there or be inside glass (the
        # coincident probe's).
        if coincident is not None:
            org_p, org_prim = None, np.take(hit_prim, idx)
            near, inside = np.take(near_h, idx), np.take(glass_h, idx)
        for depth in range(ctx.settings.gather_depth + 1):
            if len(idx) == 0:
                break
            # Most of a camera chunk's time is spent here: poll the stop flag per step.
            if should_cancel is not None and should_cancel():
                raise Cancelled()
            counters.gather_rays += len(idx)
            counters.count("gather", level, len(idx))
            per_ray = np.ndim(ray_cls) > 0
            cls = c(ray_cls, np.int64) if per_ray else _NO_CLASS
            tp = c(tp, np.float64)
            bvh = _closest_bvh(ctx.accel, ray_cls)
            meet = coincident is not None and bool(near.any())
            esc = None
            # (the rays' hit rows and throughputs before the compaction: those missing
            # from its hits escaped into the world)
            world_esc = ((idx.copy(), tp.copy()) if world is not None and depth == 0
                         and level == 0 else None)
            if turned_refl is not None and depth > 0 and turned_refl.escapes:
                # The rays whose chain took a turned reflection, before the hits are
                # compacted in place: those missing after it escaped.
                tsel = np.nonzero(turned_h[idx])[0]
                if len(tsel):
                    esc = (idx[tsel], np.take(d, tsel, axis=0), np.take(tp, tsel, axis=0),
                           np.take(np.broadcast_to(ray_cls, (len(idx),)), tsel))
            glass_from = coincident is not None and not meet and bool(inside.any())
            if glass_from:
                # (idx is compacted in place below: the rays' origins by hit row)
                from_h[idx] = org_prim
            if meet:
                if org_p is None:
                    org_p = np.take(p, idx, axis=0)
                # Rays leaving a glass face another surface touches, or that surface into
                # the glass, meet the other one there, and rays inside the glass reaching
                # the floor under it leave the glass first (engine/coincident.py): the
                # hits as Accel.intersect answers them (the same values as below), the
                # probe's hits put in, then compacted.
                t, prim, u, v = ctx.accel.intersect(o, d, cls=ray_cls)
                coincident.meet(o, d, org_p, org_prim, t, prim, u, v, inward=True)
                m = keep_hits(prim, o, d, tp, idx, u, v, t, cls)
            elif bvh is not None and not fog_escapes:
                # Embree from a kernel into this thread's buffers (Accel.intersect_hits),
                # the hits compacted from its answer (gatherkernels.keep_embree_hits):
                # intersect's numbers without its conversions and fresh arrays.
                nr = len(idx)
                o32, d32, tf32 = buf.o32[:nr], buf.d32[:nr], buf.tf32[:nr]
                rays_f32(o, d, o32, d32, tf32)
                out = buf.geom[:nr], buf.prim32[:nr], buf.u32[:nr], buf.v32[:nr]
                starts = bvh.intersect_hits(o32, d32, tf32, out=out)[4]
                prim, u, v, t = buf.prim[:nr], buf.u[:nr], buf.v[:nr], buf.t[:nr]
                m = keep_embree_hits(*out, tf32, starts, o, d, tp, idx, cls, prim, u, v, t)
            else:
                t, prim, u, v = ctx.accel.intersect(o, d, cls=ray_cls)
                if fog_escapes:
                    _gather_escaping(ctx, scatter, glow, world_row, prim, o, d, tp, idx,
                                     medium_h, E, G, rng, counters)
                # The hits, compacted in place (gatherkernels.keep_hits).
                m = keep_hits(prim, o, d, tp, idx, u, v, t, cls)
            if world_esc is not None and m < len(world_esc[0]):
                # The rays that met nothing straight from their hit: the world.
                alive = np.zeros(n, np.bool_)
                alive[idx[:m]] = True
                gone = np.flatnonzero(~alive[world_esc[0]])
                world[0][world_esc[0][gone]] += world_esc[1][gone] * world[1]
            world_esc = None
            if m < len(idx):
                o, d, tp, idx, prim, u, v, t = (a[:m] for a in (o, d, tp, idx, prim, u, v, t))
                if per_ray:
                    ray_cls = cls[:m]
            if esc is not None:
                # (the rays missing from the compacted hits escaped into the sun: a
                # light hit by the ray of the path's last scatter, which Cycles counts
                # if the vertex it left was within every Light Paths limit (the kernel
                # limit is the setting + 1, docs/design.md, Bounce limits): the chain's
                # counts before its last continuation, cnt_in, plus the gather's own
                # diffuse bounce. cnt, after it, held one bounce too many: a glass of
                # water seen through 4 refractions lost light at Max Bounces 10-16)
                missed = np.flatnonzero(~np.isin(esc[0], idx))
                if len(missed):
                    rows = esc[0][missed]
                    bent = (cnt_in[rows] if cnt_in is not None
                            else np.zeros((len(rows), 4), np.int64))
                    within = chaincounts.within(chaincounts.camera_counts(
                        bent, (level + 1, level + 1, 0, 0)), lim)
                    rows, missed = rows[within], missed[within]
                    Lt = turned_refl.escaped(esc[1][missed], esc[3][missed])
                    np.add.at(E, rows, esc[2][missed] * (math.pi / G) * Lt)
            if m == 0:
                break
            if glass_from:
                # Rays inside a glass standing on the floor that reach the floor under it
                # leave the glass first (engine/coincident.py).
                coincident.meet(o, d, None, np.take(from_h, idx), t, prim, u, v,
                                leaving=False)
            if medium_h is not None:
                # Gather rays that travelled inside an absorbing medium keep
                # exp(-sigma_a s) of the segment (engine/media.py). (A new array: the
                # buffer's throughput rows stay ones.)
                tp_seg = tp
                tp = media.attenuated(ctx.geo, sigma, prim, d, t, tp, medium_h[idx])
                tp = heterogeneous.attenuated(ctx, tp, o, d, t, prim)
                if glow is not None:
                    # The glow of an emitting medium along the ray (as a gather ray's
                    # radiance: x pi / G).
                    src, Le = glow.along(prim, d, t, medium_h[idx], o=o)
                    if len(src):
                        E[np.take(idx, src)] += np.take(tp_seg, src, axis=0) * math.pi * Le / G
                if scatter is not None:
                    # The lamps' light a scattering medium sends along the ray (single
                    # scattering, engine/volumescatter.py): the fog's glow on the surface.
                    # (at the first hit: the distances' numbers stratified over the
                    # pixel's samples, one dimension per gather ray, as the camera's)
                    g_uv = None
                    if (sampler is not None and volumescatter.STRATIFIED
                            and GATHER_VOLUME_STRATIFIED):
                        try:
                            g_uv = sampler.subset(np.asarray(idx)).uv(("gather-volume", g))
                        except KeyError:
                            g_uv = None
                    src, Ls = scatter.radiance(prim, o, d, t, medium_h[idx], rng, counters,
                                               g_uv)
                    if len(src):
                        E[np.take(idx, src)] += np.take(tp_seg, src, axis=0) * math.pi * Ls / G
            fp_y = (None if fp_start is None
                    else transfer_footprint(fp_h[idx], spread_h[idx], t))
            y = surface_hit(ctx.geo, ctx.table, prim, u, v, d, unguarded=(
                None if turned_refl is None else turned_refl.unguarded(ctx.geo, prim, u, v)),
                footprint=fp_y)
            if fp_y is not None:
                # (the regathers, the glow's second bounce and the chain's next rays go on
                # from these ends)
                y.footprint, y.spread = fp_y, spread_h[idx]
            if level > 0 and depth == 0 and not glow_only:
                Le = _linked_emission(ctx, y.emission, prim, hit.prim, idx)
                if np.any(Le > 0):
                    E[idx] += tp * math.pi * Le / G
            elif depth == 0 and unsampled:
                # The emission of sides no shadow ray samples (Emission Sampling): these
                # rays are the only strategy that finds it (the shadow rays find the rest).
                Le = _linked_emission(ctx, y.emission, prim, hit.prim, idx)
                if np.any(Le > 0):
                    Le = unsampled_emission(ctx, unsampled, prim, d, Le)
                    E[idx] += tp * math.pi * Le / G
            elif depth > 0 and passed is not None:
                _passed_emission(ctx, passed, chains, unsampled, y, prim, d, tp, idx,
                                 hit.prim, E, G)
            if t_h is not None and depth > 0:
                # Chains whose last pass reached the limit end here (Cycles'
                # PATH_RAY_TERMINATE_ON_NEXT_SURFACE): their emission is counted above;
                # no lookup, no continuation.
                on = np.flatnonzero(np.take(t_h, idx) < t_limit)
                if len(on) < m:
                    if len(on) == 0:
                        break
                    o, d, tp, idx, prim, u, v, t = (np.take(a, on, axis=0) for a in (
                        o, d, tp, idx, prim, u, v, t))
                    if per_ray:
                        ray_cls = np.take(ray_cls, on)
                    y = y.take(on)
                    m = len(on)
            if lean is None:
                wd = c(lobe_weights(ctx.table, y)["diffuse"], np.float64)
                yf = y
            else:
                # The other hits (full) alone take the closures.
                wd, full = buf.wd[:m], buf.full[:m]
                n_full = lean_diffuse(y.mat, y.base, lean, table_alpha, wd, full)
                full = full[:n_full]
                yf = y if n_full == m else y.take(full)
                if n_full:
                    wd[full] = lobe_weights(ctx.table, yf)["diffuse"]
            # Lookup inputs of the rows with a diffuse lobe (gatherkernels.diffuse_lookups).
            dsel, lp, ln = buf.dsel[:m], buf.lp[:m], buf.ln[:m]
            loff, lt = buf.loff[:m], buf.lt[:m]
            nd = diffuse_lookups(wd, y.p, y.ng, y.offset, t, dsel, lp, ln, loff, lt)
            ends = dsel[:nd].copy() if second_glow and nd else None
            if nd and gmap is not None:
                dsel = dsel[:nd]
                # The regathers add the secondary caustic back from the lookups' own
                # points where the map holds it (_point_secondary).
                sec_E = gmap.secondary_E if regather else None
                got = gmap.lookup(lp[:nd], ln[:nd], offset=loff[:nd], scratch=buf,
                                  points=sec_E is not None or cnt is not None,
                                  surface=hit_surfaces(ctx, np.take(y.prim, dsel)))
                Ey, boundary = got[:2]
                if cnt is not None:
                    _chain_lookups(ctx, level, cnt[idx[dsel]], Ey, boundary, lt[:nd],
                                   regather, gmap, got[2])
                again = buf.again[:nd]
                n_again = add_gathered(E, idx, dsel, tp, wd, Ey, G, boundary, lt[:nd],
                                       float(ctx.gather_short), regather, again)
                if n_again:
                    if ends is not None:
                        # (regathered later with every light, the glow among them)
                        ends = np.delete(ends, again[:n_again])
                    # Gathered again later, all in one batch (_regather).
                    rows = dsel[again[:n_again]]
                    pending.append((idx[rows] + (0 if clamp is None else g * n),
                                    np.take(tp, rows, axis=0),
                                    np.take(wd, rows, axis=0), prim[rows], u[rows],
                                    v[rows], np.take(d, rows, axis=0),
                                    None if cnt is None else cnt[idx[rows]],
                                    None if sec_E is None else
                                    _point_secondary(sec_E, got[2][again[:n_again]]),
                                    None if t_h is None else t_h[idx[rows]],
                                    None if fp_start is None else np.take(y.footprint, rows),
                                    None if fp_start is None else np.take(y.spread, rows)))
            if ends is not None and len(ends):
                # The glow that lights the ends (one ray each: their irradiance from the
                # emitting media, Eg), reflected by their diffuse lobe towards the
                # gathering hit as a lookup's irradiance would be.
                y_end = y.take(ends)
                y_end.medium = (None if medium_h is None
                                else np.take(medium_h[idx], ends))
                Eg = gather_indirect(ctx, y_end, rng, counters, rays=1, level=level + 1,
                                     should_cancel=should_cancel, lean=lean,
                                     extra=None if cnt is None else cnt[idx[ends]],
                                     glow_only=True,
                                     passes=None if t_h is None else t_h[idx[ends]])
                add_gathered(E, idx, c(ends, np.int64), c(tp, np.float64),
                             c(wd, np.float64), c(Eg, np.float64), G, _NO_FLAG,
                             _NO_LENGTH, 0.0, False, _NO_ROWS)
            choice = None
            if chains is not None and (yf is y or n_full):
                # The chain's hits with a lobe to continue: blurred, and light sampling
                # through their blurred reflective lobes (glossysplit.GatherChains).
                rows_f = slice(None) if yf is y else full
                choice = chains.vertex(yf, idx[rows_f], tp[rows_f], E_chain, G, rng,
                                       counters, counts=None if cnt is None else
                                       chaincounts.camera_counts(cnt[idx[rows_f]],
                                                                 chains.D_BOUNCE),
                                       depth=depth,
                                       used=None if t_h is None else t_h[idx[rows_f]])
            if depth == ctx.settings.gather_depth:
                break
            d_in = d
            pdf = None
            if yf is y:
                keep, o, d, tp, ray_cls, *pdf, pass_lobe = continue_specular(
                    ctx, y, tp, rng, ray_cls, choice=choice, want_pdf=chains is not None,
                    want_pass=True)
                keep_f = keep
            else:
                # Lean hits never continue (no lobe but the diffuse one); the survival
                # numbers are drawn for every hit, as continue_specular draws them.
                go_u = rng.random(m)
                if not n_full:
                    break
                keep, o, d, tp, ray_cls, *pdf, pass_lobe = continue_specular(
                    ctx, yf, tp[full], rng, ray_cls[full] if np.ndim(ray_cls) else ray_cls,
                    go_u=go_u[full], choice=choice, want_pdf=chains is not None,
                    want_pass=True)
                keep_f = keep
                keep = full[keep]
            if cnt is not None and len(keep):
                # A chain whose counts at this hit are past a Light Paths limit ends here,
                # as Cycles ends the path: each lookup after it is past too
                # (_chain_lookups' rule) and so is its next ray's escape (cnt_in). This,
                # not a fixed cap, bounds the chain's length (settings.gather_depth).
                on = chaincounts.within(chaincounts.camera_counts(
                    cnt[idx[keep]], (level + 1, level + 1, 0, 0)), lim)
                if not on.all():
                    on = np.flatnonzero(on)
                    keep, keep_f, o, d, tp, ray_cls, pass_lobe = (
                        np.take(a, on, axis=0)
                        for a in (keep, keep_f, o, d, tp, ray_cls, pass_lobe))
                    pdf = [np.take(x, on) for x in pdf]
            if passed is not None:
                passed.step(prim, d_in, y.p, idx, keep, d)
            if t_h is not None and len(keep):
                # The pass lobe's continuations are transparent passes (a volume-only
                # surface's aside), as the camera chain counts them.
                passed_k = pass_lobe.copy()
                if t_vol is not None:
                    passed_k &= ~np.take(t_vol, np.take(y.mat, keep))
                t_h[idx[keep]] += passed_k
            if chains is not None:
                chains.continued(idx[keep], pdf[0], keep_f, d, passed=pass_lobe)
                lamps = chains.emission(idx[keep], o, d, tp, ray_cls, E_chain, G,
                                        counts=None if cnt is None else
                                        chaincounts.camera_counts(cnt[idx[keep]],
                                                                  chains.D_BOUNCE),
                                        used=None if t_h is None else t_h[idx[keep]],
                                        left=np.take(prim, keep))
                if lamps is not None:
                    # The lamps the continued rays passed count as the camera chain's
                    # passes; a chain whose pass reached the limit ended at the lamp.
                    if t_h is not None:
                        t_h[idx[keep]] += lamps[0]
                    if lamps[1].any():
                        on = np.flatnonzero(~lamps[1])
                        keep, keep_f, o, d, tp, ray_cls, pass_lobe = (
                            np.take(a, on, axis=0)
                            for a in (keep, keep_f, o, d, tp, ray_cls, pass_lobe))
                        pdf = [np.take(x, on) for x in pdf]
            if turned_refl is not None and turned_refl.escapes:
                turned_h[idx[keep]] = (turned_h[idx[keep]]
                                       | turned_refl.turned(y, keep, d_in[keep], d))
            if coincident is not None:
                org_p = np.take(y.p, keep, axis=0)
                org_prim = np.take(prim, keep)
                near = coincident.near(org_p, org_prim)
                inside = np.take(coincident.is_glass, org_prim)
            if medium_h is not None:
                # Refracted or passed into a medium, or out of it (into the world
                # volume's, if any).
                medium_h[idx[keep]] = media.after_continuation(
                    ctx.geo, sigma, prim, d_in, keep, d, medium_h[idx], outside=world_row)
            if fp_start is not None:
                fp_h[idx[keep]] = np.take(y.footprint, keep)
            idx = idx[keep]
            if turned_refl is not None and turned_refl.escapes:
                # (the counts before this continuation: an escape's, above)
                cnt_in = None if cnt is None else cnt.copy()
            cnt = _count_continuations(cnt, n, idx, pass_lobe, ray_cls)
    if pending:
        _regather(ctx, E if clamp is None else E_rays.reshape(G * n, 3), pending, G, rng,
                  counters, level, should_cancel, lean)
    if clamp is None:
        return E
    w, limit = clamp
    wG = w * G
    for g in range(G):
        E_out += sampleclamp.clamp(E_rays[g], wG, None, limit)
        if chain_rays is not None:
            chain_out += sampleclamp.clamp(chain_rays[g], wG, None, limit)
    return E_out


def _gather_pass_counts(ctx, n, passes, lamps=False):
    """(t_limit, t_h, t_vol) for gather_indirect's chains: Light Paths > Max Bounces >
    Transparent (at least 1, as the camera chain's), t_h (n,) int64 each hit row's
    transparent bounces (filled per gather step from passes) or None where no chain can
    reach the limit (no material a ray passes, no lamp the chains pass (lamps: whether
    they may meet one) and no count given), t_vol (M,) bool the volume-only materials
    (their pass is none, path_state_volume_next) or None."""
    table = ctx.table
    t_limit = max(int(ctx.settings.transparent_max_bounces), 1)
    counted = passes is not None and np.any(passes)
    if not counted and not n:
        return t_limit, None, None
    if (not counted and not lamps
            and not ShadowTransmittance.transparent_materials(table).any()):
        return t_limit, None, None
    vol = getattr(table, "volume_only", None)
    t_vol = np.asarray(vol, bool) if vol is not None and np.any(vol) else None
    return t_limit, np.zeros(n, np.int64), t_vol


def _passed_emission(ctx, passed, chains, unsampled, y, prim, d, tp, idx, from_prim, E, G):
    """E[idx] += the emission the gather rays (hits y, triangles prim (m,), directions d,
    throughputs tp (m,3), gathering hit rows idx (m,)) meet past their first hit across
    window glass and transparent passes alone (passed: GatherPassages), as a first hit
    counts it: at level 0 the mesh sides no shadow ray samples (unsampled:
    _unsampled_meshes; D's shadow rays carry the sampled sides through those surfaces),
    at a regather level (unsampled empty) every emissive mesh (its direct light skips
    them); the photons through those surfaces are direct-kind, in no map the gathering
    hit reads (docs/compatibility.md "passages48"). With Filter Glossy's split (chains)
    the rays from a blurred vertex are left to the chains' emission
    (glossysplit.GatherChains.emission), which counts those sides already."""
    if y.emission is None:
        return
    rows = passed.clear_rows(idx)
    if chains is not None and len(rows):
        rows = rows[~np.take(chains.from_blurred, np.take(idx, rows))]
    if not len(rows):
        return
    Le = np.asarray(y.emission, np.float64)[rows]
    if not np.any(Le > 0):
        return
    at = np.take(idx, rows)
    Le = _linked_emission(ctx, Le, prim[rows], from_prim, at)
    if unsampled:
        Le = unsampled_emission(ctx, unsampled, prim[rows], np.take(d, rows, axis=0), Le)
    E[at] += np.take(tp, rows, axis=0) * math.pi * Le / G


def _gather_escaping(ctx, scatter, glow, world_row, prim, o, d, tp, idx, medium_h, E, G,
                     rng, counters):
    """E[idx] += the lamps' light the world volume scatters (scatter: CameraScattering,
    None: it does not scatter) and its own glow (glow: volumeemission.MediumEmission,
    None: no medium emits) along the gather rays (o, d (n,3), throughput tp (n,3),
    gathering hit rows idx (n,)) that escape the scene (prim (n,) -1) in it
    (medium_h[idx] == world_row), x pi / G as a gather ray's radiance
    (engine/worldmedium.py escaping: the whole length until the medium's transmittance
    is 1e-13; engine/volumescatter.py radiance)."""
    esc, esc_prim, esc_t = worldmedium.escaping(ctx, prim, d, medium_h[idx], world_row)
    if len(esc) == 0:
        return
    esc_d = np.take(d, esc, axis=0)
    esc_m = np.take(medium_h[idx], esc)
    if scatter is not None:
        src, Ls = scatter.radiance(esc_prim, np.take(o, esc, axis=0), esc_d, esc_t, esc_m,
                                   rng, counters)
        if len(src):
            rows = esc[src]
            E[np.take(idx, rows)] += np.take(tp, rows, axis=0) * math.pi * Ls / G
    if glow is not None:
        src, Le = glow.along(np.full(len(esc), -1, np.int64), esc_d, esc_t, esc_m,
                             o=np.take(o, esc, axis=0))
        if len(src):
            rows = esc[src]
            E[np.take(idx, rows)] += np.take(tp, rows, axis=0) * math.pi * Le / G


def _glow_without_hit(ctx, glow, acc, target, pix, prim, o, d, t, tp, medium, world_row):
    """The camera paths' glow (glow: volumeemission.MediumEmission) along the segments
    that meet no surface: those ending on a lamp (prim (n,) -2, t (n,) the lamp's
    distance in units of |d| (n,3)) in a known medium (medium (n,) int64 >= 0), and those
    escaping (prim -1) through the world volume (medium == world_row >= 0;
    worldmedium.escaping's length); into pass `target` of acc at pixels pix (n,),
    weighted by tp (n,3); o (n,3) the segments' origins."""
    lamp = np.flatnonzero((prim == -2) & (np.asarray(medium) >= 0))
    esc, _, esc_t = worldmedium.escaping(ctx, prim, d, medium, world_row)
    rows = np.concatenate([lamp, esc])
    if len(rows) == 0:
        return
    seg_t = np.concatenate([np.take(t, lamp), esc_t])
    src, Le = glow.along(np.full(len(rows), -1, np.int64), np.take(d, rows, axis=0), seg_t,
                         np.take(medium, rows), o=np.take(o, rows, axis=0))
    if len(src):
        acc.add(target, pix, Le, tp, rows[src])
        if acc.light is not None:
            acc.light.met(pix, Le, tp, rows[src], lightpasses.EMISSION)


def _count_continuations(cnt, n, idx, passed, ray_cls):
    """The gather rays' counts (n,4) per gathering hit after a continuation step
    (B_TOTAL order, as the camera chain and Cycles' path_state_next count them: a ray of
    any lobe but the transparent pass is a bounce of its continued class, an IOR 1 or
    normal-incidence refraction's unbent ray too; sheen's rays (DIFFUSE) a diffuse one;
    a pass none). cnt: (n,4) before (None: zeros), updated in place; idx (K,) the
    continued rays' hits (one ray a hit); passed (K,) bool the pass lobe's rays
    (continue_specular's want_pass)."""
    if len(idx) == 0:
        return cnt
    # One compiled pass (gatherkernels.count_bounces): integer counts.
    c = np.ascontiguousarray
    passed = c(passed, np.bool_)
    if cnt is None:
        if not count_bounces(_NO_COUNTS, _NO_ROWS, passed, _NO_ROWS, DIFFUSE, GLOSSY,
                             TRANSMISSION):
            return None
        cnt = np.zeros((n, 4), np.int64)
    cls = c(np.broadcast_to(np.asarray(ray_cls, np.int64), (len(idx),)))
    count_bounces(cnt, c(idx, np.int64), passed, cls, DIFFUSE, GLOSSY, TRANSMISSION)
    return cnt


_NO_COUNTS = np.zeros((0, 4), np.int64)  # count_bounces: only whether a ray is a bounce
_NO_ROWS = np.zeros(0, np.int64)


def _chain_lookups(ctx, level, cnt, Ey, boundary, lt, regather, gmap, point):
    """Gather lookups at `level` whose rays have bounces cnt (K,4) beyond the level's own
    (chaincounts): those past a limit read nothing and are not gathered again (Ey 0,
    boundary False, lt inf); those whose counts drop more light than the level's map
    holds gather again from their end (boundary True, with regather); the others whose
    counts drop some of the map's photons (every one at the last level) read the
    irradiance of their usable photons alone at their gather point (point (K,) int64,
    GatherMap.lookup's; chaincounts.subset_irradiance). Ey (K,3), boundary, lt (K,): the
    lookups' arrays, changed in place; gmap: the level's GatherMap."""
    counts = chaincounts.camera_counts(cnt, (level + 1, level + 1, 0, 0))
    limits = ctx.settings.bounce_limits
    past = ~chaincounts.within(counts, limits)
    if past.any():
        Ey[past] = 0.0
        boundary[past] = False
        lt[past] = np.inf
    gc = ctx.gather_counts
    if gc is None:
        return
    read = ~past & (point >= 0)
    if regather:
        again = gc.reroute(level, counts) & ~past
        if again.any():
            boundary[again] = True
        # (a boundary row gathers again: its Ey is not read)
        read &= ~boundary
    if not LOOKUP_SUBSETS:
        if not regather:
            keys, which = chaincounts.unique_counts(counts)
            scale = np.array([gc.kept_share(level, tuple(int(x) for x in k))
                              if gc.drops(level, tuple(int(x) for x in k)) else 1.0
                              for k in keys])[which]
            Ey[~past] *= scale[~past, None]
        return
    if getattr(gmap, "estimating", None) is None or not read.any():
        return
    # The map's irradiance holds the dropped photons' power too, and their share of a
    # point's light is their share where they lie, not the map's (a closed sphere of
    # Glass + Diffuse sides at 8 bounces read 1.53x Cycles when the last level scaled
    # the map by the whole map's kept share; docs/accuracy.md, gatherlevel44).
    rows = np.flatnonzero(read)
    rows = rows[gc.partial(level, counts[rows])]
    # (most points' estimates hold none of the photons those counts drop: E as it is)
    rows = rows[chaincounts.may_drop(gmap, level, counts[rows], point[rows])]
    if len(rows):
        Ey[rows] = chaincounts.subset_irradiance(gmap, limits, counts[rows], point[rows])


def _deeper(pmap, deeper, level):
    """The map for lookups `level` diffuse bounces deeper than pmap's own: deeper[level -
    1] (Context.regather_maps / regather_secondary), pmap at level 0 or without them."""
    return pmap if level == 0 or len(deeper) < level else deeper[level - 1]


class GatherBuffers:
    """The arrays of one gather level's steps, kept by one thread between its calls:
    fresh arrays of a few MB per step fault their pages in on first touch (and fault in
    parallel on two workers). rays(n) hands out the gather rays' rows (row of the
    gathering hit (n,) int64, origins, directions, throughput (n,3)); the other fields
    hold rows for as many rays as the largest call had (a step's rays and ends are never
    more than its first rays): the ends' fields (diffuse weight wd (m,3), full (m,),
    dsel (m,), lookup point lp, normal ln (m,3), offset loff, ray length lt (m,), again
    (m,)); the uniform numbers of a gather without a sampler uv (2n,); Embree's rays and
    answer (o32, d32 (n,3), tf32, u32, v32 (n,) float32; geom, prim32 (n,) int32) and
    the hits kept from it (prim (n,) int64, u, v, t (n,)); GatherMap.lookup's scratch
    (scratch_arrays(m)); and `direct`, the DirectLightBuffers of this level's regathers."""

    def __init__(self):
        self.size = -1  # (-1: a first call for 0 rows still makes its empty arrays)
        # The regathers' direct light from this level's ends (_regather): its sums are
        # read before the level below (which has its own) runs.
        self.direct = DirectLightBuffers()
        self.tp_ones = 0  # leading rows of tp known to hold 1.0 (gather_indirect)

    def rays(self, n):
        if n > self.size:
            self.size = n
            self.idx, self.full, self.dsel, self.again = (np.empty(n, np.int64)
                                                           for _ in range(4))
            self.o, self.d, self.tp, self.wd, self.lp, self.ln = (np.empty((n, 3))
                                                                  for _ in range(6))
            self.loff, self.lt = np.empty(n), np.empty(n)
            self.uv = np.empty(2 * n)
            self.o32, self.d32 = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32)
            self.tp_ones = 0  # (a new tp: not filled yet)
            self.tf32, self.u32, self.v32 = (np.empty(n, np.float32) for _ in range(3))
            self.geom, self.prim32 = np.empty(n, np.int32), np.empty(n, np.int32)
            self.prim = np.empty(n, np.int64)
            self.u, self.v, self.t = np.empty(n), np.empty(n), np.empty(n)
            self.q_out = np.empty((n, 3))
            self.q_boundary, self.q_blocked = np.empty(n, np.bool_), np.empty(n, np.bool_)
            self.q_row = np.empty(n, np.int64)
            self.q_point = np.empty(n, np.int64)
        return self.idx[:n], self.o[:n], self.d[:n], self.tp[:n]

    def scratch_arrays(self, m):
        """GatherMap.lookup's arrays for m rows (m <= size): (out (m,3), boundary (m,)
        bool, o32, d32 (m,3) float32, t32 (m,) float32, ray_row (m,) int64, blocked (m,)
        bool, point (m,) int64). Its visibility rays reuse the step's Embree rays (o32,
        d32, tf32), which the step has read by then (keep_embree_hits)."""
        return (self.q_out[:m], self.q_boundary[:m], self.o32[:m], self.d32[:m],
                self.tf32[:m], self.q_row[:m], self.q_blocked[:m], self.q_point[:m])


def _closest_bvh(vis, ray_cls):
    """The Embree BVH (accel.Accel, with intersect_hits) that answers closest-hit rays of
    class ray_cls (scalar, or per ray) exactly as vis.intersect(..., cls=ray_cls) does,
    or None where that needs more (per-ray classes over class subsets, a subset's
    triangle map, two-level instances)."""
    if getattr(vis, "has_invisible", False):
        if np.ndim(ray_cls) > 0:
            return None
        bvh = vis.for_class(ray_cls)
    else:
        bvh = getattr(vis, "full", vis)
    return bvh if hasattr(bvh, "intersect_hits") else None


def _gather_buffers(ctx, level) -> GatherBuffers:
    """The calling thread's GatherBuffers for gather level `level`, held by the render's
    context (dropped with it; a context made for worker threads, Context.serial, is one
    render's)."""
    bufs = vars(ctx).get("_gather_buffers")
    if bufs is None:
        bufs = vars(ctx).setdefault("_gather_buffers", {})  # (atomic under the GIL)
    key = (threading.get_ident(), level)
    buf = bufs.get(key)
    if buf is None:
        buf = bufs[key] = GatherBuffers()
    return buf


def _spawn(rng: np.random.Generator) -> np.random.Generator:
    """A child stream of rng that draws nothing from it: numpy's Generator.spawn(1)[0]
    (numpy >= 1.25), written out from the bit generator's SeedSequence so the same
    numbers come on the older numpy some Blender releases embed."""
    bits = rng.bit_generator
    seq = getattr(bits, "seed_seq", None) or bits._seed_seq
    return np.random.Generator(type(bits)(seq.spawn(1)[0]))


def _regather(ctx, E, pending, G, rng, counters, level, should_cancel, lean):
    """Gather once more from the ends of gather rays whose lookup is not to be trusted
    (gather_indirect's regathers), all of one gather_indirect call in one batch: direct
    light by shadow rays, one gather ray of level + 1 and the secondary caustic at the
    ends, added into E (M,3) at their target rows with weight tp x wd / G (several ends
    may add to one row). pending: per gather step (target (K,) int64, tp (K,3), wd (K,3),
    prim (K,), u, v (K,), d (K,3), extra (K,4) or None, secondary (K,3) or None: the
    secondary caustic of the lookups' points, NaN rows none: _point_secondary) of the
    ends, then passes (K,) int64 or None: the ends' chains' transparent bounces (their
    shadow rays cross the passes left, their gather goes on counting from there), then
    footprint (K,) m and spread (K,) rad or None: the ends' ray footprint and dD
    (SurfaceHit.footprint, spread; bump.transfer_footprint). The
    surface data are recomputed from the rays' hits (surface_hit is row by row:
    the same values the step had). Random numbers:
    a stream spawned from rng (_spawn, which draws nothing from rng), so the same for any
    worker count as the chunk's own."""
    extras = [p[7] for p in pending]
    if all(e is None for e in extras):
        extra = None
    else:
        extra = np.concatenate([np.zeros((len(p[0]), 4), np.int64) if p[7] is None else p[7]
                                for p in pending])
    if all(p[8] is None for p in pending):
        known = None
    else:
        known = np.concatenate([np.full((len(p[0]), 3), np.nan) if p[8] is None else p[8]
                                for p in pending])
    if all(p[9] is None for p in pending):
        passes = None
    else:
        passes = np.concatenate([np.zeros(len(p[0]), np.int64) if p[9] is None else p[9]
                                 for p in pending])
    # (the ends' footprints and dD, if every step had them: bump.transfer_footprint)
    foot = None
    if all(p[10] is not None for p in pending):
        foot = tuple(np.concatenate([p[k] for p in pending]) for k in (10, 11))
    target, tp, wd, prim, u, v, d = (np.concatenate(a) if len(pending) > 1 else a[0]
                                     for a in zip(*(p[:7] for p in pending)))
    rng = _spawn(rng)
    # At most REGATHER_BATCH ends at a time (one stream, slice after slice): the level's
    # arrays stay bounded however many ends a chunk regathers.
    for a in range(0, len(target), REGATHER_BATCH):
        b = a + REGATHER_BATCH
        _regather_batch(ctx, E, target[a:b], tp[a:b], wd[a:b], prim[a:b], u[a:b], v[a:b],
                        d[a:b], G, rng, counters, level, should_cancel, lean,
                        None if extra is None else extra[a:b],
                        None if known is None else known[a:b],
                        None if passes is None else passes[a:b],
                        None if foot is None else (foot[0][a:b], foot[1][a:b]))


# Ends a regather batch holds at most (its surface data, direct-light buffers and the next
# level's gather buffers: ~1-2 KB an end). A window-lit room regathered ~1 end per camera
# sample per level, 2.1x estimate_memory's peak at 128 spp in one batch per chunk.
REGATHER_BATCH = 1 << 15


def _regather_batch(ctx, E, target, tp, wd, prim, u, v, d, G, rng, counters, level,
                    should_cancel, lean, extra=None, known=None, passes=None, foot=None):
    """_regather for one slice of its ends (rng: the batch's spawned stream); extra: the
    ends' bounces beyond their level's (gather_indirect's; None: none); known: (K,3) the
    ends' secondary caustic from their lookups' points, NaN rows none (None: none);
    passes: (K,) int64 the ends' transparent bounces (None: 0); foot: ((K,) m, (K,) rad)
    the ends' ray footprint and dD (SurfaceHit.footprint, spread; None: not known)."""
    if passes is not None and not passes.any():
        passes = None
    y = surface_hit(ctx.geo, ctx.table, prim, u, v, d,
                    footprint=None if foot is None else foot[0])
    if foot is not None:
        y.footprint, y.spread = foot
    # The lookup held light from caustics one bounce back (the CAUSTIC_DIFFUSE photons);
    # the gather below cannot see caustics (kept out of the gather map), so add that
    # light here.
    # (direct_irradiance's sums live in this level's buffers until the next regather
    # batch of this level on this thread; the sum below reads them first.)
    # (The ends are level + 1 diffuse bounces from the camera's hit: their secondary
    # caustic comes from that level's map, bounce limits: docs/design.md.)
    counters.count("regathered", level + 1, len(target))
    before = counters.shadow_rays
    Ed = direct_irradiance(ctx, y, rng, counters, skip_mesh_lights=True,
                           buffers=_gather_buffers(ctx, level).direct,
                           counts=chaincounts.camera_counts(
                               np.zeros((1, 4), np.int64) if extra is None else extra,
                               (level + 1, level + 1, 0, 0)), used=passes)
    counters.count("regather shadow", level + 1, counters.shadow_rays - before)
    Esub = (Ed
            + gather_indirect(ctx, y, rng, counters, rays=1, level=level + 1,
                              should_cancel=should_cancel, lean=lean, extra=extra,
                              passes=passes)
            + _secondary_irradiance(ctx, y, rng, level + 1, extra, known))
    c = np.ascontiguousarray
    add_gathered(E, target, np.arange(len(target), dtype=np.int64), c(tp, np.float64),
                 c(wd, np.float64), c(Esub, np.float64), G, _NO_FLAG, _NO_LENGTH, 0.0,
                 False, _NO_ROWS)


# Placeholders for gatherkernels' optional arguments (a scalar ray class; the second
# add_gathered call, which regathers nothing).
_NO_CLASS = np.zeros(0, np.int64)
_NO_FLAG = np.zeros(0, np.bool_)
_NO_LENGTH = np.zeros(0)
_NO_ROWS = np.zeros(0, np.int64)


# A regathered point's secondary-caustic estimate (a k-NN query, ~100 Embree traversals)
# is a smooth term averaged over many gather rays: evaluate it for this fraction of them,
# weighted up (Russian roulette on the estimate: unbiased). Evaluating all of them took
# 45 % of Figure 7's camera pass once that map had a radius of its own. 0.25 -> 0.1 took
# 1 CPU s of 9 off Figure 7 and of 13 off issue 14's Principled spheres at the same
# HDR-FLIP (docs/accuracy_time_principled_spheres.md).
SECONDARY_REGATHER_FRACTION = 0.1

# A regathered end's secondary caustic from the gather point its lookup found
# (GatherMap.secondary_E: the CAUSTIC_DIFFUSE photons' share of that point's estimate, from
# the map build's own searches), at every end; the k-NN estimate above only where the
# lookup found no point. The term is ~0.2 % of Figure 7's gathered light and its k-NN
# estimate at a tenth of the ends was ~12 % of the render (docs/performance.md,
# regather29). False: the k-NN estimate at every end (a tenth of them), as before.
SECONDARY_FROM_GATHER_POINTS = True


def _point_secondary(sec_E, point):
    """(K,3) of sec_E's dtype (float32 levels, hdri52): sec_E[point] (GatherMap.secondary_E
    at the lookups' gather points),
    NaN rows where point is -1 (no point found: _secondary_irradiance estimates those)."""
    out = np.take(sec_E, np.maximum(point, 0), axis=0)
    out[point < 0] = np.nan
    return out


def _secondary_irradiance(ctx, hit, rng, bounces=0, extra=None, known=None):
    """Irradiance (N,3) from caustic light one diffuse bounce back (CAUSTIC_DIFFUSE
    photons) at regathered points. known: (N,3) or None, the points' values from their
    lookups' gather points (GatherMap.secondary_E, _point_secondary), taken as they are
    where the rows' counts (extra) keep every photon of the map (chaincounts.keeps_every_photon: after
    a specular chain some limit may drop some); the other rows, NaN rows (no point) and
    every row without known are estimated from the secondary map for a random
    SECONDARY_REGATHER_FRACTION of them and weighted by its inverse (zero elsewhere).
    bounces: the points' diffuse bounces from the camera's hit (the map of that depth:
    Context.regather_secondary); extra: (N,4) their bounces beyond that
    (gather_indirect's; None: none), the estimate then from the photons usable for
    their counts alone (chaincounts.irradiance)."""
    pmap, s = _deeper(ctx.secondary_map, ctx.regather_secondary, bounces), ctx.settings
    out = np.zeros((len(hit.p), 3))
    if pmap is None or len(pmap) == 0:
        return out
    # (the numbers are drawn for every row, known or not)
    pick = rng.random(len(hit.p)) < SECONDARY_REGATHER_FRACTION
    if known is not None:
        have = ~np.isnan(known[:, 0])
        if extra is not None:
            bent = np.flatnonzero(have & np.any(extra != 0, axis=1))
            if len(bent):
                have[bent] = chaincounts.keeps_every_photon(
                    pmap, s.bounce_limits,
                    chaincounts.camera_counts(extra[bent], (bounces, bounces, 0, 0)))
        out[have] = known[have]
        pick &= ~have
    rows = np.nonzero(pick)[0]
    if len(rows):
        counts = (None if extra is None else
                  chaincounts.camera_counts(extra[rows], (bounces, bounces, 0, 0)))
        radius = ctx.secondary_radius or ctx.global_radius
        prim = getattr(hit, "prim", None)
        surface = hit_surfaces(ctx, None if prim is None else prim[rows])
        if PHOTON_VISIBILITY:
            # (One search a row for the estimate and its visibility rays.)
            E = photonvisibility.visible_irradiance(
                pmap, getattr(ctx, "accel", None), hit.p[rows], hit.ng[rows],
                None if getattr(hit, "offset", None) is None else hit.offset[rows], radius,
                s.k_nearest, smooth_min_photons(s), s.estimator, limits=s.bounce_limits,
                counts=counts, geo=getattr(ctx, "geo", None), surface=surface)
        else:
            E = chaincounts.irradiance(pmap, s.bounce_limits, counts, hit.p[rows],
                                       hit.ng[rows], radius, s.k_nearest,
                                       smooth_min_photons(s), s.estimator, surface=surface)
        out[rows] = E / SECONDARY_REGATHER_FRACTION
    return out


def lobe_choice(albedo, tp):
    """The continuation's lobe choice from the hits' lobe albedos albedo (N, N_LOBES, 3)
    (bsdf.closures) and throughputs tp (N,3): (sel (N, N_LOBES) the probability of
    continuing through each lobe (diffuse: 0; Russian roulette included), q (N,) the
    survival probability, p (N, len(SPEC_LOBES)) the unnormalised lobe weights, psum (N,)).
    One compiled kernel (camerakernels.choose_lobes)."""
    n = len(albedo)
    sel = np.empty((n, len(SPEC_LOBES) + 1))
    q = np.empty(n)
    p = np.empty((n, len(SPEC_LOBES)))
    psum = np.empty(n)
    choose_lobes(np.ascontiguousarray(albedo, np.float64), np.ascontiguousarray(tp, np.float64),
                 sel, q, p, psum)
    return sel, q, p, psum


# A constant world's light through the camera's first hits' reflective lobes, its escaping
# part by splitting (world_probes): the reflected light is W int f cos 1_escape (the world
# W where the reflection meets nothing) plus int f cos L 1_meets (the surfaces it meets).
# The first part is estimated by the mean over the real continuation and WORLD_PROBES
# further reflections sampled from the same lobe choice (each an independent, unbiased
# sample of W f cos / pdf 1_escape), the second by the continuation alone, as before. Every
# term is >= 0; each part keeps its mean and its light pass (Glossy Direct), and the
# continuation's weight and roulette noise on the world is shared out over WORLD_PROBES + 1
# samples (docs/performance.md "cvpositive46"). The continuation counts as q samples (q its
# Russian roulette's survival probability; the probes always go on): the escape's share
# of the continuation is q / (q + K), each probe's 1 / (q + K).
# 0: the continuation alone, as Cycles (which samples no light for a constant world).
WORLD_PROBES = 2
# The probes' directions from the first hit's stratified sampler (dimensions ("probe", j),
# after every other: no other stream moves); False: plain random numbers.
PROBES_STRATIFIED = True
# The lobes probed: reflective, sampled with a density or a mirror, continued as GLOSSY
# rays; the pass, glass and translucent lobes (which leave the surface's far side) never.
# (Not sheen's: Cycles counts its bounce as diffuse, so its world light would belong to
# the Diffuse light passes, and its lobe is seldom alone.)
_PROBED_LOBES = np.array([name in ("metal", "spec", "coat") for name in SPEC_LOBES])


def probed_world(ctx, modes, clamping, medium, world_row, links, catchers):
    """(3,) float64 the radiance of a constant world that the camera's first hits'
    reflective lobes meet only by their continuation (MODE_CONTINUATION: no shadow rays),
    for the probes (WORLD_PROBES; _trace_paths); None where they do not apply: no such
    world, an environment map (its own light sampling), light portals, a world volume or
    any medium, Light Linking, shadow catchers, Cycles' clamps (which hold each sample's
    light, which a split changes)."""
    if WORLD_PROBES <= 0 or clamping or medium is not None \
            or world_row >= 0 or links is not None or catchers is not None:
        return None
    world = constant_world(ctx)
    if world is None or modes[world[0]] != MODE_CONTINUATION:
        return None
    return world[1]


def constant_world(ctx):
    """(li, radiance (3,) float64): the scene's one world light's index and its colour
    where it is constant (no environment map, no light portals, no world volume) and
    lights something; None otherwise (probed_world, world_gather)."""
    worlds = [li for li, light in enumerate(ctx.lights) if light.kind == WORLD]
    if len(worlds) != 1:
        return None
    light = ctx.lights[worlds[0]]
    if light.environment is not None or len(getattr(light, "portal_rects", ())):
        return None
    scene = ctx.scene
    if getattr(scene, "environment", None) is not None or worldmedium.active(scene):
        return None
    bg = np.asarray(worldmedium.background(scene, np.array([[0.0, 0.0, 1.0]])),
                    np.float64)[0]
    return (worlds[0], bg.copy()) if np.all(np.isfinite(bg)) and np.any(bg > 0) else None


def probe_rows(p, psum, over=None):
    """(K,) int64: the hits (rows of choose_lobes' p (N, len(SPEC_LOBES)), psum (N,))
    whose continued lobes are all _PROBED_LOBES (some weight, none elsewhere): every ray
    they continue is a GLOSSY reflection. over (N,) bool: hits past a bounce limit (no
    continuation), left out."""
    p = np.asarray(p)
    ok = (np.asarray(psum) > 0) & ~(p[:, ~_PROBED_LOBES] > 0).any(axis=1)
    if over is not None:
        ok &= ~np.asarray(over, bool)
    return np.flatnonzero(ok)


def world_probes(ctx, hit, tp, choice, rows, world, rng, counters, uv, t_limit, used=None):
    """The escaping world light of WORLD_PROBES further reflections at the hits rows (K,)
    (of hit, throughputs tp (N,3)), each sampled again from the hit's lobe choice
    (continue_specular with every row surviving, from rng, a stream of its own) and
    tested for escape as the continuation's ray would meet it (an occlusion ray of class
    GLOSSY; the lamps glossy rays see are passed, unless t_limit (Light Paths > Max
    Bounces > Transparent, at least 1 as _trace_paths': no default, so no caller probes
    with a limit of its own; less used (N,) int64: the passes each path made before the
    hit; None: none) of them lie on the way: lamp_passes, one lamp counted at one
    distance: first_at_each_distance). Returns (hit rows (M,),
    light (M,3) with its throughput: world x tp x f cos / pdf / P(lobe) / (q + K), q the
    hit's survival probability, K = WORLD_PROBES), the rows of escaped probes, a row
    once per probe; every value >= 0. uv: a function of the probe's index j giving its
    stratified numbers (u1, u2) (N,) (continue_specular's uv), or None: random ones."""
    n = len(tp)
    q = np.asarray(choice[1], np.float64)
    k = WORLD_PROBES
    go_u = np.full(n, 2.0)  # (not probed: fails u < q)
    go_u[rows] = 0.0
    out_rows, out_L = [], []
    for j in range(k):
        uv_j = None if uv is None else functools.partial(uv, j)
        keep, o, d, tpk = continue_specular(ctx, hit, tp, rng, GLOSSY, choice=choice,
                                            go_u=go_u, uv=uv_j)[:4]
        if not len(keep):
            continue
        escaped = ~ctx.accel.occluded(o, d, None, cls=GLOSSY)
        counters.shadow_rays += len(keep)
        # (occlusion rays from the camera's first hits: counted with their shadow rays)
        counters.count("camera shadow", 0, len(keep))
        # A lamp on the way hides no world (the ray goes on past it, _trace_paths),
        # unless the passes through the lamps reach Max Bounces > Transparent (t_limit):
        # the path ends at the lamp, as lamp_passes.
        met = np.zeros(len(keep), np.int64) if used is None else np.take(used, keep)
        if escaped.any():
            # (no Light Linking to apply: probed_world runs no probes with links)
            for entry in lamps_met(ctx, o, d, np.full(len(o), np.inf), GLOSSY)[0]:
                met[entry[2]] += 1
        escaped &= met < t_limit
        sel = np.flatnonzero(escaped)
        r = keep[sel]
        # (continue_specular divides by q; a probe always goes on: times q, over q + K)
        qr = q[r]
        w = tpk[sel] * (qr / (qr + k))[:, None]
        out_rows.append(r)
        out_L.append(w * world)
    if not out_rows:
        return np.zeros(0, np.int64), np.zeros((0, 3))
    return np.concatenate(out_rows), np.concatenate(out_L)


def passes_past_limit(table, hit, over, d, tp, ray_cls):
    """The transparent passes of camera-chain hits past a bounce limit (over (N,) bool):
    Cycles sets up only the Transparent BSDF on a path flagged
    PATH_RAY_TERMINATE_AFTER_TRANSPARENT (bsdf_transparent_setup: num_closure_left 1) and
    samples it with probability 1, so such a path still goes on through see-through
    surfaces, unbent, with its throughput x the transparency (1 - alpha) x tint, and
    collects the light beyond (a glossy surface inside a transparent sphere: the
    reflected ray's light through the sphere's near side was lost, 0.86 x Cycles at Max
    Bounces 0; docs/design.md, Bounce limits). Returns (rows, origins (K,3), directions
    (K,3), throughput (K,3), ray class (K,), pdf (K,) inf) of the hits with a pass share,
    d (N,3), tp (N,3) and ray_cls (N,) being the incoming rays'."""
    rows = np.flatnonzero(over)
    params = hit.params if hit.params is not None else table.closure_params
    at = rows if hit.params is not None else np.take(hit.mat, rows)
    a = np.take(_hit_alpha(table, hit), rows)
    w = (1.0 - a)[:, None] * params[at, pr.M_TTINT:pr.M_TTINT + 3]
    ok = (w > 0).any(axis=1)
    rows, w = rows[ok], w[ok]
    dk = np.ascontiguousarray(np.take(d, rows, axis=0), np.float64)
    cls = np.broadcast_to(np.asarray(ray_cls, np.int64), (len(over),))
    return (rows, hit.clear(rows, dk), dk, np.take(tp, rows, axis=0) * w,
            np.take(cls, rows), np.full(len(rows), np.inf))


# The camera's first hits choose the lobe to continue as Cycles picks a closure
# (studio56): by the lobes' albedos' mean channel (Cycles' sample weights;
# camerakernels.shade_lobes' mean_weights) instead of the max channel that later bounces,
# the photons and the Filter Glossy split's pdfs keep, and with a number stratified over
# the pixel's samples (lobe_numbers). False: as before (kept to measure the difference:
# docs/accuracy.md "studio56").
FIRST_HIT_MEAN_WEIGHTS = True
FIRST_HIT_LOBE_STRATIFIED = True


def lobe_numbers(sampler, key, rng):
    """One uniform number (N,) per path of sampler (StratifiedSampler) stratified over its
    pixel's samples in one dimension: the 2-D dimension key's numbers (u1, u2) on its m x m
    grid, whose cells each sample visits once, made 1-D as (floor(m u1) + u2) / m, so the
    pixel's m^2 samples fall one in each interval [k / m^2, (k + 1) / m^2). The first hit's
    lobe choice (continue_specular's lobe_u) takes them, as Cycles picks a closure with its
    stratified sampler's third BSDF dimension (surface_shader_bsdf_pick with rand_bsdf.z):
    a coat over a metal, picked with probability ~0.07, was then picked in 1 of 16 samples
    or in 0-3 of them, by chance (studio56). rng: the jitter's generator."""
    u1, u2 = sampler.uv(key, rng=rng)
    m = sampler.m
    if m < 2:
        return u1
    cx = np.minimum(np.floor(u1 * m), m - 1)
    return np.minimum((cx + u2) / m, np.nextafter(1.0, 0.0))


def _spawned_lobe_numbers(sampler, bsdf_rng):
    """lobe_numbers for the camera pass' first hits, the jitter from a child of bsdf_rng."""
    return lobe_numbers(sampler, ("lobe",), bsdf_rng.spawn(1)[0])


def continue_specular(ctx, hit, tp, rng, ray_cls=CAMERA, choice=None, want_pdf=False,
                      uv=None, go_u=None, split=None, want_pass=False, lobe_u=None):
    """Pick one non-diffuse lobe per ray in proportion to its weight (Russian roulette for
    paths that would add little) and sample it. Returns (kept indices, origins, directions,
    throughput, ray class of the continued rays: glossy, transmission, or ray_cls (the
    incoming class, scalar or per ray) through a transparent pass) and, with want_pdf, the
    pdf (N,) of each continued direction under the whole choice (inf: from a mirror-like
    lobe, a refraction or a pass, which light sampling cannot produce). The throughput
    takes the sampled direction's own weight (f cos / pdf) over the choice probability, so
    the lobe weights only steer the choice. choice: lobe_choice(albedo, tp) if already made.
    Two compiled kernels (camerakernels.pick_lobes, continue_lobes) with the uniform numbers
    drawn between them in numpy, in a fixed order. uv: (u1, u2) (N,) stratified numbers
    (the first hit's sampler) for the sampled lobes' directions instead of plain random
    ones: a glossy highlight, where the lobe is narrower than the light and the lobes'
    sampling carries it, is far calmer with its directions stratified over the pixel's
    samples (as Cycles' are); or a function returning them, called only when a reflective
    lobe is sampled. go_u: the survival test's uniform numbers (N,), drawn by the caller
    (gather_indirect draws them for all its hits and continues only those with a
    non-diffuse lobe); default: drawn here. split: (N,) bool, the hits where a picked
    smooth glass lobe (rough too with SPLIT_ROUGH_GLASS) continues both its reflection and
    its refraction, each with its Fresnel weight (camerakernels.glass_both): one kept
    index may then appear twice, and two last elements are returned, (K,) bool, the rays a
    split made, and (K,) float64, the probability with which Cycles' glass sampling would
    have chosen each such ray's half (camerakernels.glass_both_share; 1 on the others).
    want_pass: one more last element, (K,) bool, the rays the transparent pass lobe made
    (a transparent bounce to Cycles; every other lobe's ray is a bounce of its kind, an
    IOR 1 refraction too, which goes on unbent).
    lobe_u: a function returning stratified numbers (N,) (lobe_numbers) for the lobe
    choice of hits with two or more lobes of weight > 0, instead of plain random ones
    (called only when such a hit continues); None: random ones.
    The same uniform numbers are drawn either way."""
    sel, q, p, psum = (choice if choice is not None
                       else lobe_choice(closures(ctx.table, hit, ctx.geo)[1], tp))
    go = (psum > 0) & ((rng.random(len(p)) if go_u is None else go_u) < q)
    idx = np.nonzero(go)[0]
    m = len(idx)
    if m == 0:
        empty = np.zeros((0, 3))
        out = (idx, empty, empty, empty, np.zeros(0, np.int64))
        out = out + (np.zeros(0),) if want_pdf else out
        out = out if split is None else out + (np.zeros(0, bool), np.zeros(0))
        return out + (np.zeros(0, bool),) if want_pass else out
    r = rng.random(m)
    if lobe_u is not None:
        # Stratified only where there is a choice: a hit of one lobe takes it whatever r.
        several = np.count_nonzero(np.take(p, idx, axis=0) > 0.0, axis=1) >= 2
        if several.any():
            r = np.where(several, np.take(lobe_u(), idx), r)
    lobe = np.empty(m, np.int64)
    prob = np.empty(m)
    c = np.ascontiguousarray
    sampled = pick_lobes(c(p), c(psum), c(q), idx, r, lobe, prob)
    # Three uniform numbers per sampled (non-pass) lobe, drawn in this order.
    u1, u2, u3 = rng.random((3, sampled))  # one draw: the same numbers as three
    if uv is not None and sampled:
        # Reflective lobes only: rough glass (IOR 2.4) in the white furnace scatters ~4x as
        # widely over seeds with stratified numbers (no bias: docs/accuracy_time.md).
        picked = lobe[lobe != PASS_LOBE]
        rows_sampled = idx[lobe != PASS_LOBE]
        refl = (picked != GLASS_R) & (picked != GLASS_T)
        if refl.any():
            u = uv() if callable(uv) else uv
            u1 = np.where(refl, u[0][rows_sampled], u1)
            u2 = np.where(refl, u[1][rows_sampled], u2)
    # The camera bounce's hits carry their packed lobes (shade_lobes); others set them up.
    prm = hit.prm if hit.prm is not None else closures(ctx.table, hit, ctx.geo)[0]
    # A split writes up to two rays for one pick.
    cap = m if split is None else 2 * m
    rows = np.empty(cap, np.int64)
    o, d, new_tp = np.empty((cap, 3)), np.empty((cap, 3)), np.empty((cap, 3))
    cls = np.empty(cap, np.int64)
    pdf = np.empty(cap if want_pdf else 0)
    split_in = _NO_SPLIT if split is None else c(split, np.bool_)
    split_out = np.empty(cap if split is not None else 0, np.bool_)
    split_p = np.empty(cap if split is not None else 0)
    # A writable copy: a read-only view would be a second kernel signature, compiled
    # during the first render instead of by jit.ensure_compiled.
    incoming = np.empty(len(p), np.int64)
    incoming[:] = ray_cls
    # The pass lobe's weight, (1 - alpha) x the Transparent BSDF's colour, in the kernel.
    alpha = _NO_ALPHA if hit.alpha is None else c(hit.alpha, np.float64)
    k = continue_lobes(idx, lobe, prob, u1, u2, u3, c(prm), c(sel), hit.mat,
                       ctx.table.closure_params, c(ctx.table.alpha, np.float64), alpha, c(hit.p),
                       c(hit.ng), c(hit.ns), c(hit.wo), c(hit.offset), c(tp, np.float64),
                       incoming, _LOBE_CLASS, bool(want_pdf), split_in,
                       bool(SPLIT_ROUGH_GLASS), rows, o, d, new_tp, cls, pdf, split_out,
                       split_p)
    out = (idx[rows[:k]], o[:k], d[:k], new_tp[:k], cls[:k])
    out = out + (pdf[:k],) if want_pdf else out
    out = out if split is None else out + (split_out[:k], split_p[:k])
    return out + (np.take(lobe, rows[:k]) == PASS_LOBE,) if want_pass else out


# Camera paths sample the lights through rough glass (engine/glasslight.py; False: the
# refraction's continuation alone finds them, as before: a sun behind a rough glass ball
# made fireflies and a dark median, issue 14).
# The final-gather rays' fog segments take stratified distance numbers at the first hit
# (("gather-volume", g), fog37); False: random (measured in docs/accuracy.md, fog37).
GATHER_VOLUME_STRATIFIED = True
# Hits reached only through transparent passes (no bent bounce yet: chain[:, 0] == 0 for
# every shaded row) shade with the stratified sampler, as first hits (fog37: the floor
# under a fog box); False: random numbers past bounce 0, as before.
UNBENT_STRATIFIED = True
GLASS_LIGHT_SAMPLING = True
_NO_ROWS = np.zeros(0, np.int64)


_NO_ALPHA = np.zeros(0)  # continue_lobes: the materials' alpha
_NO_SPLIT = np.zeros(0, np.bool_)  # continue_lobes: no glass lobe is split
# A camera path's first glass hits continue both halves of the glass lobe, each with its
# Fresnel weight, instead of one chosen with it (_trace_paths; docs/performance.md,
# "Glass speckles: splitting the camera's first glass hits"). A glass ball under a sun
# behind the camera showed rare samples of the sun's full radiance: its mirror image on
# the ball's front, taken by the ~4 % of samples whose choice took the reflection, and
# (most of them) the ball's rainbow, the path in, reflected at the back and out, whose
# inner reflection was the rare choice. Deeper glass hits keep the random choice, as
# Cycles' do. How many glass hits of a camera path split: 2 takes the rainbow's inner
# reflection (a sun-lit glass ball: pixel variance x CPU s 16 -> 1.0; 1 split: 20);
# 0: the choice everywhere, as before.
SPLIT_GLASS_HITS = 2
# Rough glass splits too, at one microfacet normal (glass_both). Its reflection keeps
# the MIS pdf of the whole choice (principled.bsdf_pdf), which light sampling's weight
# also uses: the two weights still sum to one, so the estimate stays unbiased.
SPLIT_ROUGH_GLASS = True
# The camera's first hits whose continuation is mirror-like only (a smooth dielectric's
# specular layer, albedo ~4 %: Russian roulette kept 40 % of them at weight 2.5) always
# continue (camerakernels.mirror_survival): light sampling cannot carry a mirror lobe.
MIRROR_NO_ROULETTE = True
_LOBE_CLASS = np.array([SPEC_LOBE_CLASS[name] for name in SPEC_LOBES], np.int64)


# Density estimates take only the photons their point can see (engine/photonvisibility.py,
# issue 14): a surface piercing the estimate's surface stops its disc.
PHOTON_VISIBILITY = True
# The caustic estimate is already a smooth kernel average, so it varies little between the
# samples of one pixel: evaluate it for at most this many samples per pixel (weighted up).
CAUSTIC_SAMPLES_PER_PIXEL = 16
# The secondary caustic (caustic light one diffuse bounce back, CAUSTIC_DIFFUSE photons)
# has been spread by a diffuse reflection: it varies within a pixel as little as the
# indirect light does, so fewer samples per pixel carry it: 16 -> 4 took 1 CPU s of 14
# off issue 14's Principled spheres, HDR-FLIP unchanged
# (docs/accuracy_time_principled_spheres.md).
SECONDARY_SAMPLES_PER_PIXEL = 4
# A caustic map of glow alone (effects: nothing focuses light; light off rough specular
# layers, roughness >= 0.3, or window glass, EffectPlan.caustics_glow_only) is as smooth
# within a pixel as the secondary caustic: as many samples a pixel carry it. At 16 spp its
# estimate at every sample was 1.1 of 5.1 CPU s of a product shot (a ball and a torus on
# a floor: 623 glow photons, 1 % of the seeds' variance), the same relMSE with 4
# (docs/performance.md "worldfast43").
GLOW_SAMPLES_PER_PIXEL = SECONDARY_SAMPLES_PER_PIXEL
# Both follow their estimate's share of the light the camera sees (worldcolour44:
# render.py sets Context.glow_per_pixel / secondary_per_pixel from glow_share /
# secondary_share, smooth_per_pixel). Taking the estimate at n of a pixel's samples
# instead of all adds the estimate's variation within the pixel, a pixel's relative
# variance of about share^2 x that variation / n, at a cost about n: variance x cost is
# least with n in proportion to the share (render.gather_count's rule). At and above
# SMOOTH_SHARE_FULL (render.GLOW_SHARE_FULL's rms share) the constants above; below it in
# proportion, rounded, never under one. A world-lit yard's glow (rms share 0.024) and
# secondary caustic took 0.5 of its 2.0 CPU s at 4 a pixel; 1 a pixel read the same
# relMSE and FLIP (docs/performance.md "worldcolour44").
SMOOTH_SHARE_FULL = 0.08
# A glow-only caustic map takes at least GLOW_LEAST_PER_PIXEL of them: window glass sends
# its refracted photons there too, and a thick pane's edges bunch them into narrow
# estimates that one sample a pixel leaves as single bright pixels (the feature matrix's
# window room behind a 2 cm slab, seeds 0-5, worst 8 x 8 block's error: 0.531 at seed 0
# with 1, 0.312 with 2, 0.237 with 4; the other seeds 0.12-0.26 at each).
GLOW_LEAST_PER_PIXEL = 2
# Hits reached through a rough lobe take the caustic estimate at every sample, not at
# CAUSTIC_SAMPLES_PER_PIXEL of them (_trace_paths; False: the stride everywhere, as before:
# bench/bench_accuracy_ab.py's @integrator.CAUSTIC_EVERY_SAMPLE_PAST_BOUNCE=False).
CAUSTIC_EVERY_SAMPLE_PAST_BOUNCE = True
# The glow map beside an aimed caustic map (render.GLOW_MAP_APART) at hits past a rough
# bounce: True takes its estimate at every such sample, as the caustic map's; False (the
# default) at its stride, as elsewhere: a rough layer's glow, smoothed over the glow cap,
# does not vary within a pixel's spread as a reflected focus does (tableroom45: every
# object's relMSE the same to 4 digits at seeds 0 and 1, fewer estimates; docs/accuracy.md).
GLOW_EVERY_SAMPLE_PAST_BOUNCE = False


def hit_surfaces(ctx, prim):
    """(M,) int32 the object ids (Geometry.object_id; an instance's own) of the hit
    triangles prim (M,) int, for the photon estimates' surface test
    (PhotonMap.knn_irradiance's surface); None without a scene Geometry (tests' bare
    contexts): the normal test alone."""
    geo = getattr(ctx, "geo", None)
    if geo is None or prim is None:
        return None
    prim = np.asarray(prim, np.int64)
    ids = np.asarray(geo.object_id[np.maximum(prim, 0)], np.int32)
    return np.where(prim >= 0, ids, np.int32(-1)).astype(np.int32)


def smooth_min_photons(settings) -> int:
    """Photons a caustic or secondary-caustic estimate needs (fewer: no estimate). The
    paper's min_photons in paper mode; else 1: with fewer than k photons the k-NN estimate
    uses every photon in the whole search disc, which is unbiased, while zeroing it below
    min_photons darkened light that reaches the caustic map thinly (issue 14: a constant
    world reflected by a rough metal ball and a glossy floor onto a diffuse ball, 2-3 % of
    the ball's light, docs/accuracy_time.md "Glossy noise against Cycles")."""
    return settings.min_photons if settings.paper_mode else 1


def _smooth_estimate(ctx, pmap, radius, hit, f, sample_id, footprint=None,
                     per_pixel=None, every=None, into=None, counts=None, clamp_tp=None,
                     blur=None):
    """f * irradiance from a photon map whose estimate is smooth within a pixel (caustic,
    secondary caustic): evaluated for at most per_pixel samples per pixel (default
    CAUSTIC_SAMPLES_PER_PIXEL) and weighted up accordingly. footprint: the pixel's radius
    on the surface; a focus is spread over at least that (a point focus hit by few
    samples makes fireflies). every: (N,) bool, rows that take the estimate at every
    sample (unweighted): hits past a rough bounce, where one pixel's samples scatter over
    the surface and a stride would multiply the estimate's noise; None: none.
    into: (N,3) float64 to add the estimate to (its rows that take one), returned; None:
    a fresh array (zero where no estimate is taken). Adding into the caller's sum at the
    estimated rows only spares an (N,3) array of mostly zeros, its fill and its sum
    (one row in `stride` takes an estimate; the other rows' x + 0.0 is x). counts:
    (N,4) the rows' camera-side bounces where they differ from the map's (after a
    specular chain: the photons usable for them alone, chaincounts.irradiance); None:
    the map's. clamp_tp: (N,3) the rows' camera-path throughputs, to hold each sample's
    estimate to Cycles' Clamp Indirect (engine/sampleclamp.py) before it is weighed up;
    None: no clamp. blur: a glossysplit.DiffusePdf of hit (Filter Glossy's split: only
    the photons Cycles does not blur count, each row's search and disc kept) or None."""
    out = np.zeros_like(f) if into is None else into
    if pmap is None or len(pmap) == 0:
        return out
    s = ctx.settings
    per_pixel = CAUSTIC_SAMPLES_PER_PIXEL if per_pixel is None else per_pixel
    stride = max(1, -(-s.spp // per_pixel)) if sample_id is not None else 1
    # An adaptive round of R samples a pixel (ctx.camera_round; sample_id its samples'
    # index in the round): the estimate at sample k * stride stands for its block
    # [k stride, min((k + 1) stride, R)) and weighs the block's length, so each round, and
    # any number of rounds a pixel stops after, is unbiased (engine/adaptive.py).
    block = getattr(ctx, "camera_round", 0) if stride > 1 else 0
    if stride > 1:
        # The samples at multiples of the stride: for a power of two (128 spp: 8 and 32)
        # the low bits by a mask, the same rows as % (two's complement: x & (s - 1) is x
        # mod s for any int64) without an integer division a row.
        on = ((sample_id & (stride - 1)) == 0 if stride & (stride - 1) == 0
              and sample_id.dtype.kind == "i" else sample_id % stride == 0)
    if stride > 1 and every is not None and every.any():
        sel = np.nonzero(on | every)[0]
        w = smooth_sample_weight(s.spp, stride) if not block else \
            np.minimum(stride, block - sample_id[sel]).astype(np.float64)
        weight = np.where(every[sel], 1.0, w)[:, None]
    else:
        sel = np.nonzero(on)[0] if stride > 1 else np.arange(len(hit.p))
        weight = smooth_sample_weight(s.spp, stride) if not block else \
            np.minimum(stride, block - sample_id[sel]).astype(np.float64)[:, None]
    # (np.take(axis=0) gathers rows several times faster than fancy indexing.)
    surface = hit_surfaces(ctx, None if getattr(hit, "prim", None) is None
                           else np.take(hit.prim, sel))
    # Clamp Indirect per photon (engine/photonclamp.py): each photon weighed as the
    # Cycles path it ends, at the rows' clamp throughput x albedo (f x pi).
    pclamp = None
    if (clamp_tp is not None and getattr(pmap.photons, "radiance", None) is not None
            and np.isfinite(sampleclamp.limits(s)[1])):
        # (each row's camera path bounce: Cycles' roulette spares the chain's hits up to
        # Min Light Bounces + 1, photonclamp.roulette_share; no counts: the first hits)
        pclamp = (np.take(clamp_tp, sel, axis=0) * (np.pi * np.take(f, sel, axis=0)),
                  sampleclamp.limits(s)[1],
                  None if counts is None else np.take(counts[:, B_TOTAL], sel))
    if PHOTON_VISIBILITY or blur is not None or pclamp is not None:
        # Only the photons each point can see (issue 14: a lamp shade piercing a wall);
        # one search a row for the estimate and its visibility rays.
        off = getattr(hit, "offset", None)
        E = photonvisibility.visible_irradiance(
            pmap, getattr(ctx, "accel", None) if PHOTON_VISIBILITY else None,
            np.take(hit.p, sel, axis=0),
            np.take(hit.ng, sel, axis=0), None if off is None else np.take(off, sel), radius,
            s.k_nearest, smooth_min_photons(s), s.estimator,
            r_floor=None if footprint is None else np.take(footprint, sel),
            limits=s.bounce_limits,
            counts=None if counts is None else np.take(counts, sel, axis=0),
            geo=getattr(ctx, "geo", None), surface=surface,
            reject=None if blur is None else blur.reject_for(pmap, sel), clamp=pclamp)
    else:
        E = chaincounts.irradiance(
            pmap, s.bounce_limits, None if counts is None else np.take(counts, sel, axis=0),
            np.take(hit.p, sel, axis=0), np.take(hit.ng, sel, axis=0), radius, s.k_nearest,
            smooth_min_photons(s), s.estimator,
            r_floor=None if footprint is None else np.take(footprint, sel), surface=surface)
    if clamp_tp is not None:
        # (Per sample, before the weight: each of the block's samples held to the limit.
        # Nothing over it: the unclamped sum below, bit for bit.)
        L = np.take(f, sel, axis=0) * E
        held = sampleclamp.clamp(L, clamp_tp, sel, sampleclamp.limits(s)[1])
        if held is not L:
            if into is None:
                out[sel] = weight * held
            else:
                out[sel] += weight * held
            return out
    if into is None:
        out[sel] = weight * np.take(f, sel, axis=0) * E
    else:
        out[sel] += weight * np.take(f, sel, axis=0) * E
    return out


def smooth_per_pixel(most: int, share: float | None, full: float | None = None,
                     least: int = 1) -> int:
    """Samples a pixel that take a smooth estimate (_smooth_estimate's per_pixel) whose
    light is rms share `share` of what the camera sees (visualimportance.glow_share /
    secondary_share; None or not finite: not known, `most`): most x share / full rounded
    to the nearest, from `least` (1; GLOW_LEAST_PER_PIXEL for a glow map) to `most`
    (SMOOTH_SHARE_FULL's comment). Rounded, not ceiled as gather_count's rays: a share
    just over a step would double the estimates.
    full: None, SMOOTH_SHARE_FULL (read at the call: A/B benches set it)."""
    if share is None or not math.isfinite(share):
        return int(most)
    full = SMOOTH_SHARE_FULL if full is None else full
    return int(min(most, max(least, math.floor(most * share / full + 0.5))))


def smooth_sample_weight(spp: int, stride: int) -> float:
    """Weight of a sample that takes a smooth estimate when one sample in `stride` of a
    pixel's spp does (sub-sample ids 0, stride, 2 stride, ... < spp): spp over the number
    of those samples, so the pixel's mean is unbiased. (The stride itself over-weighted
    whenever spp is not a multiple of it: +5 % at 100 spp with 16 estimates a pixel.)"""
    return spp / -(-spp // stride)


# A constant world at a diffuse hit is found by its shadow rays (cosine-distributed, n_s a
# sample: effects' plan.light_samples) and by the final gather's rays that escape (cosine-
# distributed too, G a sample): the same pdf, so the two strategies' balance-heuristic
# weights are n_s / (n_s + G) and G / (n_s + G), and every ray of either kind counts
# 1 / (n_s + G) of the world's f x pi x L (Veach 1997, sec. 9.2; the multi-sample
# estimator). Before (False), the gather rays that escaped were thrown away: the world's
# direct light read n_s rays' visibility where n_s + G had been traced (docs/
# performance.md "worlds56"). Cycles finds a constant world by its BSDF ray alone.
WORLD_GATHER_MIS = True


def world_gather(ctx, clamping: bool):
    """(li, G, scale) for WORLD_GATHER_MIS at the camera's diffuse hits: li the constant
    world's light index, G the final gather's rays a hit at level 0, scale (3,) float64
    pi x L_world / (n_s + G) (the irradiance one escaping gather ray of throughput 1 adds
    to the direct term; n_s the world's shadow rays a sample); None where it does not
    apply: no final gathering, a Light Paths limit below one diffuse bounce, no world or
    not a constant one (an environment map: its own light sampling), light portals (the
    shadow rays' pdf is a mixture), the world not sampled by shadow rays, the light tree,
    Light Linking, transparent shadows, panes or shades (their light samples share the
    world's count), absorbing media or a world volume, objects some ray class does not
    see, guided gather rays (not cosine-distributed), or a Cycles clamp on the hit's light
    (clamping: Clamp Direct at the camera's first hit, Clamp Indirect past it; each ray
    is held apart). (Lamps' surfaces stop neither kind of ray: the gather rays and the world's
    shadow rays pass them alike, as Cycles' rays pass its lamps.)"""
    s = ctx.settings
    if not WORLD_GATHER_MIS or clamping or not s.photon_mapping:
        return None
    if getattr(ctx, "gather_map", None) is None or s.gather_rays <= 0:
        return None
    lim = s.bounce_limits
    if lim[0] < 1 or lim[1] < 1:
        return None  # (gather_indirect traces no ray at level 0)
    world = constant_world(ctx)
    if world is None:
        return None
    li, bg = world
    light = ctx.lights[li]
    if (not light.ray_kinds & SHADOW or not light.shadow_sampled or
            ctx.plan.light_samples.get(light.name, 0) <= 0):
        return None
    if (selector_for(ctx, False) is not None or getattr(ctx, "links", None) is not None
            or getattr(ctx, "shadow", None) is not None or panes_for(ctx) is not None
            or shades_for(ctx) is not None):
        return None
    if (media.absorption_table(ctx.table).shape[0] or worldmedium.medium_row(ctx) >= 0
            or getattr(ctx.accel, "has_invisible", False)
            or getattr(ctx.gather_map, "guide", None) is not None):
        return None
    G = s.gather_rays
    n_s = ctx.plan.light_samples[light.name]
    return li, G, bg * (math.pi / (n_s + G))


def shade_diffuse(ctx, hit, wd, rng, counters, sampler=None, sample_id=None, footprint=None,
                  should_cancel=None, glossy=None, sel=None, buffers=None, scattered=None,
                  rows=None, bounce=None, extra=None, clamp_tp=None, shade_glossy=None,
                  glossy_out=None, used=None):
    """Radiance from the diffuse lobe, split into (direct, caustic, indirect); caustic and
    indirect are None without photon mapping. glossy (N,)
    bool: hits whose rough reflective lobes also take shadow rays (light_modes); the direct
    term then holds both lobes' response (shadow rays weighted by the full BSDF, with
    multiple importance sampling against the continuation's choice sel (N, N_LOBES),
    lobe_choice). buffers: the calling thread's directlight.DirectLightBuffers (direct is
    then their sums, valid until their next use; None: fresh arrays). scattered: (N,) bool,
    hits reached through a rough lobe, whose caustic estimate is taken at every sample
    (_smooth_estimate's every); None: none.
    rows (K,) int64: shade rows `rows` of the batch `hit` (a camera bounce's shaded rows:
    the direct stage reads them in place, direct_irradiance's rows); wd, the sampler,
    sample_id, footprint, glossy, scattered and the results are per row of rows, sel is
    the whole batch's. The same numbers as shade_diffuse(hit.take(rows), ...) with sel
    taken at rows. None: every hit.
    bounce: the camera path's bounce, for counters.stages' ("camera shadow", bounce): the
    direct stage's shadow rays (the final gather's regathers count their own).
    extra: (K,4) int64 per shaded row, the camera chain's bounces before these hits
    (B_TOTAL order; the photon lookups count only the photons usable after them,
    engine/chaincounts.py); None: none (the camera's first hits).
    clamp_tp: (K,3) per shaded row, the camera path's throughput: the photon estimates
    (indirect light) are held to Cycles' Clamp Indirect per sample (engine/sampleclamp.py;
    the direct term is the caller's to clamp); None: no clamp.
    shade_glossy: direct_irradiance's (the rows whose glossy lobes took the lamps through
    shades), written when glossy rows take shadow rays; None: not asked. glossy_out:
    direct_irradiance's (the glossy lobes' part of direct), with glossy rows.
    used: (K,) int64 per shaded row, the transparent bounces its camera path made
    (direct_irradiance's; the final gather's chains count on from it: gather_indirect's
    passes); None: 0."""
    f = wd / math.pi
    counters.diffuse_hits += len(hit.p) if rows is None else len(rows)
    shadow_rays_before = counters.shadow_rays
    # The constant world's light by the shadow rays and the escaping gather rays
    # (WORLD_GATHER_MIS; None: by the shadow rays alone).
    # (Cycles clamps a diffuse hit's world light, by shadow ray or escaping BSDF ray, with
    # Clamp Direct at the camera's first hit and Clamp Indirect past it: film_clamp_light's
    # bounce. Blender's defaults, Direct 0 and Indirect 10, leave the first hits unclamped.)
    if bounce is None:
        clamped = clamp_tp is not None or sampleclamp.enabled(ctx.settings)
    else:
        clamped = bool(np.isfinite(sampleclamp.limits(ctx.settings)[1 if bounce else 0]))
    wg = world_gather(ctx, clamped)
    wsh = None if wg is None else wg[:2]
    if glossy is not None and glossy.any():
        direct = direct_irradiance(ctx, hit, rng, counters, sampler, bsdf=(f, hit.prm, sel),
                                   buffers=buffers, rows=rows, counts=extra,
                                   shade_glossy=shade_glossy, glossy_out=glossy_out,
                                   used=used, world_gather=wsh)
    else:
        direct = direct_irradiance(ctx, hit, rng, counters, sampler, buffers=buffers,
                                   rows=rows, counts=extra, used=used, world_gather=wsh)
        np.multiply(f, direct, out=direct)  # f x E, in place
    if bounce is not None:
        counters.count("camera shadow", bounce, counters.shadow_rays - shadow_rays_before)
    if not ctx.settings.photon_mapping:
        return direct, None, None  # (no caustic or indirect term to add)
    if rows is not None:
        hit = hit.take(rows)  # the photon estimates read the rows' fields (copied on read)
    if glossy is not None:
        # Photon estimates only where the diffuse lobe is (glossy-only rows add nothing).
        dsel = np.nonzero(max3(wd) > 0)[0]
        if len(dsel) < len(wd):
            caustic = np.zeros_like(direct)
            indirect = np.zeros_like(direct)
            sub = hit.take(dsel)
            if sampler is not None:
                sampler = sampler.subset(dsel)
            seen = None if wg is None else (np.zeros((len(dsel), 3)), wg[2])
            c, ind = _photon_terms(ctx, sub, f[dsel], rng, counters, sampler,
                                   None if sample_id is None else sample_id[dsel],
                                   None if footprint is None else footprint[dsel],
                                   should_cancel, None if scattered is None else scattered[dsel],
                                   None if extra is None else extra[dsel],
                                   None if clamp_tp is None else clamp_tp[dsel],
                                   None if used is None else used[dsel], world=seen)
            caustic[dsel] = c
            indirect[dsel] = ind
            if seen is not None:
                # (a new array: direct may be the direct stage's buffers)
                direct = direct.copy()
                direct[dsel] += f[dsel] * seen[0]
            return direct, caustic, indirect
    seen = None if wg is None else (np.zeros_like(f), wg[2])
    caustic, indirect = _photon_terms(ctx, hit, f, rng, counters, sampler, sample_id,
                                      footprint, should_cancel, scattered, extra, clamp_tp,
                                      used, world=seen)
    if seen is not None:
        direct = direct + f * seen[0]  # (a new array, as above)
    return direct, caustic, indirect


def _shade_subsurface(ctx, sss, walks, hit, dsel, acc, pix, tp, chain, medium, sample_id,
                      footprint, bounce, rng, counters, should_cancel, clamping, lpass,
                      clamp_tp=None, used=None):
    """The BSSRDF part of a camera bounce's subsurface hits: walks (j, W, per_walk) from
    SubsurfaceWalks.entries at the shaded rows dsel, walked (SubsurfaceWalks.exits) and
    each exit shaded as a Lambertian surface of weight W x the walk's throughput (direct
    light, caustic and indirect estimates), added where the entry's own diffuse share
    goes (the same passes and bounce limits). clamp_tp: _add_lamp_light's. used: (N,)
    int64 per batch row, the transparent bounces its camera path made (None: 0): the
    exits' shadow rays and gather chains count on from the entry's (Cycles' walk keeps
    the path's transparent_bounce)."""
    s = ctx.settings
    j, W, per_walk = walks
    ctp = tp if clamp_tp is None else clamp_tp
    every = len(dsel) == len(hit.p)
    got = sss.exits(hit, None if every else dsel, j, W, rng, per_walk)
    if got is None:
        return
    i, xhit, xw = got
    rows = np.asarray(dsel)[j[i]]
    if medium is not None:
        xhit.medium = np.take(medium, rows)
    if hit.min_ray_pdf is not None:  # (the entry's path's, for the exits' gather chains)
        xhit.min_ray_pdf = np.take(hit.min_ray_pdf, rows)
    direct, caustic, indirect = shade_diffuse(
        ctx, xhit, xw, rng, counters, None,
        None if sample_id is None else np.take(sample_id, rows),
        None if footprint is None else np.take(footprint, rows), should_cancel,
        bounce=bounce, extra=None if bounce == 0 else _chain_counts(chain[rows]),
        clamp_tp=np.take(ctp, rows, axis=0) if clamping else None,
        used=None if used is None else np.take(used, rows))
    if clamping:
        direct = sampleclamp.clamp(direct, ctp, rows, sampleclamp.bounce_limits(
            s, np.take(chain[:, 0], rows)))
    if lpass is not None:
        lpass.shaded(pix, direct, tp, rows, lightpasses.DIFFUSE_DIRECT)
    _add_diffuse(acc, pix, tp, rows, chain, bounce, s.bounce_limits[0], direct, caustic,
                 indirect)
    if lpass is not None and caustic is not None:
        # (after _add_diffuse: past the Diffuse limit the indirect estimate is dropped
        # from the passes as from the image)
        lpass.shaded(pix, caustic + indirect, tp, rows, lightpasses.DIFFUSE_INDIRECT)


def _add_diffuse(acc, pix, tp, rows, chain, bounce, diffuse_limit, direct, caustic,
                 indirect) -> None:
    """Add rows' diffuse shading (direct, caustic, indirect (R,3); caustic None: no photon
    terms) to the effect passes: at the camera's first hit each to its own; past a bent
    bounce all to "specular", the indirect estimate zeroed in place where final
    gathering's added diffuse bounce passes diffuse_limit (Light Paths > Diffuse: the
    gather map holds the photons valid one diffuse bounce after the camera's first hit,
    render._build_maps; the chain's bounces are not subtracted from them further,
    docs/design.md, Bounce limits)."""
    if bounce == 0:
        acc.add("direct", pix, direct, tp, rows)
        if caustic is not None:
            acc.add("caustic", pix, caustic, tp, rows)
            acc.add("indirect", pix, indirect, tp, rows)
        return
    if caustic is not None:
        past = chain[rows, 0] + 1 > diffuse_limit
        if past.any():
            indirect[past] = 0.0
    acc.add("specular", pix, direct if caustic is None else direct + caustic + indirect,
            tp, rows)


def _caustic_per_pixel(ctx) -> int:
    """Samples a pixel taking the caustic map's estimate: GLOW_SAMPLES_PER_PIXEL, or the
    glow's share's (Context.glow_per_pixel), for a glow-only map; else
    CAUSTIC_SAMPLES_PER_PIXEL."""
    if getattr(getattr(ctx, "plan", None), "caustics_glow_only", False):
        return getattr(ctx, "glow_per_pixel", 0) or GLOW_SAMPLES_PER_PIXEL
    return CAUSTIC_SAMPLES_PER_PIXEL


def _secondary_per_pixel(ctx) -> int:
    """Samples a pixel taking the secondary map's estimate: the share's
    (Context.secondary_per_pixel), else SECONDARY_SAMPLES_PER_PIXEL."""
    return getattr(ctx, "secondary_per_pixel", 0) or SECONDARY_SAMPLES_PER_PIXEL


# Clamp Indirect per gather ray (gather_indirect's clamp), as Cycles clamps each path;
# False: on the mean of a camera sample's G rays. Off for a while (clampray53: it took
# the smooth glass of water from 0.983 to 0.877 of *unclamped* Cycles); against Cycles'
# own clamp there (0.54 of its unclamped image) it is the nearer: with the per-photon
# clamp 1.14 of clamped Cycles, 1.33 without it (docs/accuracy.md "clampphoton54").
CLAMP_PER_GATHER_RAY = True


def _gather_clamp(s, clamp_tp, f):
    """gather_indirect's clamp for the hits of _photon_terms (clamp_tp (K,3) their camera
    paths' clamp throughput, None: no clamp; f (K,3) the diffuse lobe's albedo / pi):
    (clamp_tp x f, Clamp Indirect's limit), or None."""
    if clamp_tp is None:
        return None
    limit = sampleclamp.limits(s)[1]
    if not CLAMP_PER_GATHER_RAY or not np.isfinite(limit):
        return None
    return (clamp_tp * f, limit)


def _photon_terms(ctx, hit, f, rng, counters, sampler, sample_id, footprint, should_cancel,
                  scattered=None, extra=None, clamp_tp=None, used=None, world=None):
    """(caustic, indirect) radiance of the diffuse lobe with f = albedo / pi; scattered,
    extra, clamp_tp, used: shade_diffuse's (each estimate clamped on its own, as Cycles
    clamps each path's contributions apart; the gather's chains count their transparent
    bounces from used, gather_indirect's passes). world: gather_indirect's (the constant
    world's irradiance by the escaping gather rays, WORLD_GATHER_MIS), or None."""
    s = ctx.settings
    if not s.photon_mapping:
        return np.zeros_like(f), np.zeros_like(f)
    # Cycles' Filter Glossy (engine/glossysplit.py; None: off): the caustic / glow maps
    # count only the photons whose paths Cycles does not blur, the final gather's chains
    # carry the rest; where no row can count one (a Lambert floor above 1 / pi) the
    # estimates are left out whole.
    fg = glossysplit.split_filter_glossy(ctx)
    d_pdf = glossysplit.DiffusePdf(ctx, hit, fg) if fg > 0.0 else None
    if d_pdf is not None and d_pdf.none_unblurred():
        caustic = np.zeros_like(f)
    else:
        caustic = _smooth_estimate(ctx, ctx.caustic_map, ctx.caustic_radius, hit, f,
                                   sample_id, footprint, _caustic_per_pixel(ctx),
                                   every=scattered, counts=extra, clamp_tp=clamp_tp,
                                   blur=d_pdf)
        if getattr(ctx, "glow_map", None) is not None:
            # The glow shot's map beside the aimed one (render.GLOW_MAP_APART): as smooth
            # within a pixel as a glow-only map, so as many estimates a pixel.
            _smooth_estimate(ctx, ctx.glow_map, ctx.glow_radius, hit, f, sample_id,
                             footprint,
                             getattr(ctx, "glow_per_pixel", 0) or GLOW_SAMPLES_PER_PIXEL,
                             every=scattered if GLOW_EVERY_SAMPLE_PAST_BOUNCE else None,
                             into=caustic, counts=extra, clamp_tp=clamp_tp, blur=d_pdf)
    if ctx.gather_map is not None:
        # (the gather chains' share of the maps' light, where Filter Glossy moves it to
        # them, into the caustic term: glossysplit)
        # (Clamp Indirect per gather ray, as Cycles clamps each of its paths:
        # gather_indirect's clamp; the mean of G rays was cut only above ~G x the limit)
        chained = np.zeros_like(f) if d_pdf is not None else None
        gclamp = _gather_clamp(s, clamp_tp, f)
        indirect = f * gather_indirect(ctx, hit, rng, counters, sampler,
                                       should_cancel=should_cancel, extra=extra,
                                       caustic=chained, passes=used, d_pdf=d_pdf,
                                       clamp=gclamp, world=world)
        if clamp_tp is not None and gclamp is None:
            # (the mean's clamp: Clamp Indirect off, only its non-finite rows zeroed, or
            # CLAMP_PER_GATHER_RAY off)
            indirect = sampleclamp.clamp(indirect, clamp_tp, None, sampleclamp.limits(s)[1])
        if chained is not None:
            chained *= f
            if clamp_tp is not None and gclamp is None:
                chained = sampleclamp.clamp(chained, clamp_tp, None,
                                            sampleclamp.limits(s)[1])
            caustic = caustic + chained
        _smooth_estimate(ctx, ctx.secondary_map, ctx.secondary_radius or ctx.global_radius,
                         hit, f, sample_id, footprint, _secondary_per_pixel(ctx),
                         into=indirect, counts=extra, clamp_tp=clamp_tp)
    elif ctx.global_map is not None and len(ctx.global_map):
        if PHOTON_VISIBILITY:
            E = photonvisibility.visible_irradiance(
                ctx.global_map, getattr(ctx, "accel", None), hit.p, hit.ng,
                getattr(hit, "offset", None), ctx.global_radius, s.k_nearest, s.min_photons,
                s.estimator, limits=s.bounce_limits, counts=extra,
                geo=getattr(ctx, "geo", None),
                surface=hit_surfaces(ctx, getattr(hit, "prim", None)))
        else:
            E = chaincounts.irradiance(ctx.global_map, s.bounce_limits, extra, hit.p, hit.ng,
                                       ctx.global_radius, s.k_nearest, s.min_photons,
                                       s.estimator,
                                       surface=hit_surfaces(ctx, getattr(hit, "prim", None)))
        indirect = f * E
        if clamp_tp is not None:
            indirect = sampleclamp.clamp(indirect, clamp_tp, None, sampleclamp.limits(s)[1])
    else:
        indirect = np.zeros_like(f)
    if ctx.gather_map is None and volumeemission.glows(ctx):
        # Emitting media light surfaces through gather rays alone (no light sampling of
        # volume emission, as in Cycles; no photons from them): the gather runs for their
        # glow even without a photon map (it then looks nothing up: its rays add the
        # glow along their segments, engine/volumeemission.py).
        gclamp = _gather_clamp(s, clamp_tp, f)
        glow = f * gather_indirect(ctx, hit, rng, counters, sampler,
                                   should_cancel=should_cancel, extra=extra, passes=used,
                                   clamp=gclamp)
        if clamp_tp is not None and gclamp is None:
            glow = sampleclamp.clamp(glow, clamp_tp, None, sampleclamp.limits(s)[1])
        indirect = indirect + glow
    return caustic, indirect


def _split_catcher_paths(ctx, acc, caught, miss, o, d, tmax, tp, pix, rng, counters,
                         cam_pos, forward, should_cancel, sampler, sample_id, bsdf_rng,
                         buffers):
    """The camera rays `caught` (N,) bool of a first bounce, whose first hit is a shadow
    catcher, traced on by _trace_paths of their own into a second Accumulator: their
    light goes into acc's sums as always and also into acc.catcher's "light", their count
    into its "coverage" (Cycles' shadow catcher sample count). Without a transparent
    film the world seen along every ray that meets a catcher or nothing goes into its
    "background" (Cycles' Background pass, which its approximate shadow catcher
    composites the shadow onto). miss (N,) bool: the rays that met nothing."""
    rows = np.nonzero(caught)[0]
    sums = acc.catcher_sums()
    if not ctx.settings.film_transparent:
        seen = np.nonzero(caught | miss)[0]
        if len(seen):
            acc.add("catcher_background", pix, worldmedium.background(
                ctx.scene, np.take(d, seen, axis=0), np.ones(len(seen), bool)), tp, seen)
    if not len(rows):
        return
    acc.add_scalar(sums["coverage"], np.take(pix, rows), np.ones(len(rows)))
    part = Accumulator(acc.npix, acc.lo)
    _trace_paths(ctx, part, np.take(o, rows, axis=0), np.take(d, rows, axis=0),
                 np.take(tmax, rows), np.take(tp, rows, axis=0), np.take(pix, rows), rng,
                 counters, cam_pos, forward, should_cancel,
                 None if sampler is None else sampler.subset(rows),
                 None if sample_id is None else np.take(sample_id, rows), bsdf_rng, buffers,
                 split_catchers=False)
    for name in Accumulator.NAMES:
        sums["light"] += part.buf[name]
    acc.merge(part)


class Accumulator:
    """Per-pixel sums for each pass over pixels [lo, lo + npix) of the region, by compiled
    scatter-adds (camerakernels.film_add, film_add_scalar, film_first_normals) that form
    each pixel's sum as np.bincount did (the same bits) without holding the GIL."""

    NAMES = ("direct", "indirect", "caustic", "specular", "emission")

    def __init__(self, npix, lo=0):
        self.npix = npix
        self.lo = lo
        self.buf = {k: np.zeros((npix, 3)) for k in self.NAMES}
        self.alpha = np.zeros(npix)
        self.holdout = np.zeros(npix)
        # Cycles' Depth: the view-axis depth of the surface each pixel's first sample
        # ends its single pass on (datapasses.add_surface), 0 where it met none; written
        # once a pixel, so chunk and round merges add it.
        self.depth = np.zeros(npix)
        self.normal = np.zeros((npix, 3))
        # Cycles' data passes asked for (engine/datapasses.py: key -> (npix,3) or (npix,)
        # sums), made when a bounce first writes them.
        self.data = {}
        # Shadow catchers (engine/shadowcatcher.py): "light" (npix,3) the light of the
        # camera rays that met a catcher first, "coverage" (npix,) their count,
        # "background" (npix,3) the world along the rays that met a catcher or nothing
        # (without a transparent film); None until a bounce meets one.
        self.catcher = None
        # The light passes' path state while _trace_paths fills this accumulator
        # (engine/lightpasses.py PathPasses; None: no light pass asked for).
        self.light = None

    def catcher_sums(self) -> dict:
        """This accumulator's shadow catcher sums (self.catcher), made when first asked."""
        if self.catcher is None:
            n = self.npix
            self.catcher = {"light": np.zeros((n, 3)), "coverage": np.zeros(n),
                            "background": np.zeros((n, 3))}
        return self.catcher

    def add(self, name, pix, rgb, tp=None, rows=None):
        """Add rgb (K,3) into pass `name`: at pixels pix (K,), or with rows (K,) int64
        at pixels pix[rows] times throughputs tp[rows] (pix (N,), tp (N,3)), without
        copying the rows out (tp without rows: K = N)."""
        if len(rgb) == 0:
            return
        rgb = np.ascontiguousarray(rgb, np.float64)
        if not rgb.flags.writeable:
            # A read-only array (one row of a broadcast colour is contiguous already) would
            # be a second kernel signature, compiled inside the render.
            rgb = rgb.copy()
        buf = (self.catcher_sums()["background"] if name == "catcher_background"
               else self.buf[name])
        film_add(buf, self.lo, pix, _ALL_ROWS if rows is None else rows,
                 _NO_TP if tp is None else tp, rgb)

    def add_scalar(self, arr, pix, w):
        """Add w (N,) into the scalar pass arr at pixels pix (N,) int64."""
        film_add_scalar(arr, self.lo, pix, np.ascontiguousarray(w, np.float64))

    def add_first_normals(self, pix, ns, front):
        """The first hits' front-facing shading normals ns (N,3) (front (N,) bool: ns as
        is, else negated) into the normal pass."""
        film_first_normals(self.lo, pix, np.ascontiguousarray(ns, np.float64), front,
                           self.normal)

    def merge(self, part: "Accumulator"):
        """Add a chunk's sums (its pixels are a window of this accumulator's)."""
        a, b = part.lo - self.lo, part.lo - self.lo + part.npix
        for name in self.NAMES:
            self.buf[name][a:b] += part.buf[name]
        for mine, theirs in ((self.alpha, part.alpha), (self.holdout, part.holdout),
                             (self.depth, part.depth), (self.normal, part.normal)):
            mine[a:b] += theirs
        for key, theirs in part.data.items():
            self._data(key, theirs)[a:b] += theirs
        if part.catcher is not None:
            for key, theirs in part.catcher.items():
                self.catcher_sums()[key][a:b] += theirs

    def _data(self, key, like):
        """This accumulator's data pass `key`, zeros of like's row shape when new."""
        if key not in self.data:
            self.data[key] = np.zeros((self.npix,) + like.shape[1:])
        return self.data[key]


_ALL_ROWS = np.zeros(0, np.int64)  # film_add: every row, in order
_NO_TP = np.zeros((0, 3))          # film_add: no throughput factor




def camera_dimensions(gather_rays: int, light_samples, extra=()) -> SampleDimensions:
    """The first-hit sampler's dimensions: ("gather", g) for each final-gather ray and
    ("light", li, si) for each shadow sample si of light li (light_samples[li] of them).
    Preferred numbers are the ones used before dimensions were allocated (gather
    1 + 64 g, light 2 + 64 li + si), so images stay as they were; they collided once a
    light took >= 63 samples (its sample 63 met gather ray li + 1, sample 64 + k met light
    li + 1's sample k). Gather rays claim first, then light samples by sample index, so
    only the later of two colliding streams moves (SampleDimensions)."""
    requests = [(("gather", g), 1 + 64 * g) for g in range(gather_rays)]
    for si in range(max(light_samples, default=0)):
        for li, n in enumerate(light_samples):
            if si < n:
                requests.append((("light", li, si), 2 + 64 * li + si))
    requests += [(key, None) for key in extra]  # e.g. the light tree's choices
    return SampleDimensions(requests)


def render_camera(ctx, region, film, progress=None, should_cancel=None,
                  on_tail=None) -> Counters:
    """The camera pass over region into film (chunks on ctx.settings.threads workers).
    on_tail(): called once the last chunk has been handed to a worker (parallel.ordered_map
    on_all_started), to start work that fills the workers the tail leaves idle."""
    s = ctx.settings
    if s.adaptive_threshold > 0:
        return render_camera_adaptive(ctx, region, film, progress, should_cancel, on_tail)
    x0, y0, x1, y1 = region
    rw, rh = x1 - x0, y1 - y0
    npix = rw * rh
    spp = s.spp
    total = npix * spp
    acc = Accumulator(npix)
    counters = Counters()
    # Chunk ci owns its random streams: the bounds depend on the image and the settings
    # only (parallel.chunk_length), never on the thread count.
    chunk = chunk_length(total, s.chunk_size)
    jobs = [(ci, (a, min(total, a + chunk))) for ci, a in enumerate(range(0, total, chunk))]
    threads = s.threads
    # Chunks on worker threads ask Embree and the kd-trees on their own thread.
    wctx = ctx.serial() if threads > 1 and len(jobs) > 1 else ctx
    dims = _camera_pass_dimensions(ctx)

    # One set of bounce arrays per thread, reused by its chunks (dropped with the render).
    buffers = {}

    def job(item, stop):
        ci, (start, end) = item
        own = buffers.setdefault(threading.get_ident(), BounceBuffers())
        return _render_chunk(wctx, region, ci, start, end, stop, dims, own)

    try:
        for part, part_counters, end in ordered_map(job, jobs, threads, should_cancel, on_tail):
            acc.merge(part)
            counters.add(part_counters)
            if progress is not None:
                # Pixels, not a percentage: the bars beside this text (Blender's, the
                # batch's) show the whole render's fraction, which differs from the pass's.
                progress("render", end / total,
                         f"Rendering pixels {short_count(end // spp)}/{short_count(npix)}")
    finally:
        _write_film(film, acc, spp, rh, rw, datapasses.wanted(s))
    return counters


def _camera_pass_dimensions(ctx) -> SampleDimensions:
    """The camera pass's sampler dimensions (camera_dimensions) for ctx's lights."""
    s = ctx.settings
    # The lens last: a depth-of-field camera adds a dimension, moving no other; then the
    # camera segments' distances in a scattering medium (volumescatter, fog37).
    lens = [("lens",)] if ctx.scene.camera.has_dof else []
    if volumescatter.scattering_tables(ctx.table) is not None:
        lens = lens + [("volume",)] + [("gather-volume", g) for g in range(s.gather_rays)]
    # Then the world probes' (world_probes), after every other: none of them moves.
    lens = lens + [("probe", j) for j in range(max(WORLD_PROBES, 0))]
    if selector_for(ctx) is not None:  # lights picked by the light tree: one stream
        S = selection_samples(s)
        # (then the lamps only glossy rays see, sampled beside the tree: last, moving none)
        glossy = [("light-glossy", li, si) for li in glossy_only_lights(ctx)
                  for si in range(ctx.plan.light_samples.get(ctx.lights[li].name, 1))]
        return camera_dimensions(s.gather_rays, [S], [("light-select", si) for si in range(S)]
                                 + [("bsdf",)] + lens + glossy + [("lobe",)])
    # The first hit's lobe choice (lobe_numbers) last: it moves no other dimension.
    return camera_dimensions(s.gather_rays, [ctx.plan.light_samples.get(li.name, 1)
                                             for li in ctx.lights], [("bsdf",)] + lens + [("lobe",)])


def render_camera_adaptive(ctx, region, film, progress=None, should_cancel=None,
                           on_tail=None) -> Counters:
    """The camera pass with adaptive sampling (settings.adaptive_threshold > 0; Cycles'
    Noise Threshold, engine/adaptive.py): rounds of samples over the pixels still active,
    a convergence check after each round past the min samples; a pixel takes between
    the min samples and spp samples. Writes film's passes (each pixel's sums over its own
    sample count) and film.sample_count (H,W) float32, Cycles' "Sample Count" pass; the
    mean samples per pixel into film.stats["adaptive_mean_spp"].

    Deterministic for any thread count: each round's chunks are cut from the round's
    sample count (parallel.chunk_length) and own random streams keyed by (seed, round,
    chunk); which pixels stay active depends on the sums only, merged in chunk order."""
    s = ctx.settings
    x0, y0, x1, y1 = region
    rw, rh = x1 - x0, y1 - y0
    npix = rw * rh
    spp = s.spp
    schedule = adaptive.Schedule(s.adaptive_threshold, s.adaptive_min_samples, spp)
    rounds = schedule.rounds()
    strides = [max(1, -(-spp // k)) for k in (_caustic_per_pixel(ctx),
                                              _secondary_per_pixel(ctx))]
    acc = Accumulator(npix)
    count = np.zeros(npix, np.int64)    # samples taken, per pixel
    half = np.zeros((npix, 3))          # radiance summed over half A (adaptive.class_a)
    count_half = np.zeros(npix, np.int64)
    active = np.arange(npix, dtype=np.int64)  # region pixels that sample this round
    counters = Counters()
    threads = s.threads
    wctx = ctx.serial() if threads > 1 else ctx
    dims = _camera_pass_dimensions(ctx)
    buffers = {}
    planned = npix * spp  # progress: samples of the whole budget
    done = 0
    try:
        for r, (a, b, check) in enumerate(rounds):
            if len(active) == 0:
                break
            R = b - a
            rctx = replace(wctx, camera_round=R, camera_round_index=r)
            total = len(active) * R
            chunk = chunk_length(total, s.chunk_size)
            jobs = [(ci, (c, min(total, c + chunk))) for ci, c in enumerate(range(0, total, chunk))]
            in_a = adaptive.class_a(np.arange(R, dtype=np.int64), r, strides)
            racc = Accumulator(2 * len(active))  # pixel j's half B at 2 j, half A at 2 j + 1

            def job(item, stop, _r=r, _R=R, _active=active, _rctx=rctx, _in_a=in_a):
                ci, (start, end) = item
                own = buffers.setdefault(threading.get_ident(), BounceBuffers())
                return _render_round_chunk(_rctx, region, _r, _R, _active, _in_a, ci, start,
                                           end, stop, dims, own)

            last = b == spp
            for part, part_counters, end in ordered_map(job, jobs, threads, should_cancel,
                                                        on_tail if last else None):
                racc.merge(part)
                counters.add(part_counters)
                if progress is not None:
                    f = (done + end) / planned
                    progress("render", f, f"Rendering adaptively: {len(active):,} "
                             f"pixels at {b} samples")
            done += total
            _add_round(acc, racc, active, half)
            count[active] += R
            count_half[active] += int(np.count_nonzero(in_a))
            if check:
                # Pixels that stopped earlier stay converged (Cycles: a converged pixel's
                # error is not computed again) unless the dilation wakes them.
                converged = np.ones(npix, bool)
                err = adaptive.pixel_error(_combined(acc, active), count[active],
                                           half[active], count_half[active])
                converged[active] = err < schedule.check_threshold
                converged = adaptive.dilate_unconverged(converged.reshape(rh, rw)).ravel()
                active = np.nonzero(~converged)[0]
    finally:
        _write_film(film, acc, np.maximum(count, 1).astype(np.float64)[:, None], rh, rw,
                    datapasses.wanted(s))
        film.sample_count = count.reshape(rh, rw).astype(np.float32)
        film.stats["adaptive_mean_spp"] = float(count.mean()) if npix else 0.0
        film.stats["adaptive_min_samples"] = schedule.min_effective
        film.stats["adaptive_threshold"] = s.adaptive_threshold
        film.stats["adaptive_spp"] = spp
    return counters


def _combined(acc, rows):
    """(len(rows),3) the sum of acc's effect passes at rows: the combined radiance."""
    out = acc.buf[Accumulator.NAMES[0]][rows].copy()
    for name in Accumulator.NAMES[1:]:
        out += acc.buf[name][rows]
    return out


def _add_round(acc, racc, active, half):
    """A round's sums racc (2 rows a pixel: half B, half A) into the pass's acc at the
    region pixels active (and half A's combined radiance into half (npix,3))."""
    for name in Accumulator.NAMES:
        both = racc.buf[name]
        acc.buf[name][active] += both[0::2] + both[1::2]
        half[active] += both[1::2]
    for mine, theirs in ((acc.alpha, racc.alpha), (acc.holdout, racc.holdout),
                         (acc.depth, racc.depth), (acc.normal, racc.normal)):
        mine[active] += theirs[0::2] + theirs[1::2]
    for key, theirs in racc.data.items():
        acc._data(key, theirs)[active] += theirs[0::2] + theirs[1::2]
    if racc.catcher is not None:
        for key, theirs in racc.catcher.items():
            acc.catcher_sums()[key][active] += theirs[0::2] + theirs[1::2]


def _render_round_chunk(ctx, region, r, R, active, in_a, ci, start, end, should_cancel,
                        dims, buffers):
    """Samples [start, end) of adaptive round r (sample = j * R + sub: the sub-th of the
    round's R samples of pixel active[j]): like _render_chunk, with the round stratified on
    its own (an m x m grid, m = floor(sqrt(R)), the sampler's scramble salted by the
    round) and the sums kept per pixel and half (2 j + in_a[sub]) in an Accumulator over
    the round's rows. Returns (acc, counters, end)."""
    s = ctx.settings
    x0, y0, x1, y1 = region
    rw = x1 - x0
    m = max(1, int(math.sqrt(R)))
    cells = m * m
    full_rounds = (R // cells) * cells
    jitter_order = np.random.default_rng(0x5EED).permutation(cells)  # (int64)
    rng = np.random.default_rng([s.seed, 7, ci, 1 + r])
    n = end - start
    counters = Counters()
    jitter = rng.random((2, n))
    idx = np.arange(start, end, dtype=np.int64)
    j, sub = idx // R, idx % R
    pix = active[j]
    px, py = x0 + pix % rw, y0 + pix // rw
    # Pixel jitter: the round's m x m grid in the scrambled order, its start shifted by a
    # hash of pixel, round and seed. Unshifted, the samples that take the strided caustic
    # and secondary estimates (sub 0, stride, ...) sat in the same cells of every pixel
    # and round: the caustic pass came out 3.5 % dark on the Figure 6 box (4 seeds,
    # docs/performance.md "adaptive").
    shift = adaptive.pixel_hash(pix, r, s.seed) % np.uint64(cells)
    cell = ((jitter_order[sub % cells].astype(np.uint64) + shift) % np.uint64(cells)).astype(np.int64)
    jx = (cell % m + jitter[0]) / m
    jy = (cell // m + jitter[1]) / m
    row = 2 * j + in_a[sub]
    lo = 2 * int(j[0])
    acc = Accumulator(2 * (int(j[-1]) - int(j[0]) + 1), lo)
    if full_rounds < R:
        rest = sub >= full_rounds
        n_rest = int(np.count_nonzero(rest))
        if n_rest:
            jx[rest], jy[rest] = rng.random((2, n_rest))
    salt = (s.seed + r * 0x9E3779B97F4A7C15) % (1 << 64)
    _trace_camera_samples(ctx, acc, row, px, py, jx, jy, sub, pix, R, rng, dims, salt,
                          np.random.default_rng([s.seed, 11, ci, 1 + r]), counters,
                          should_cancel, buffers)
    return acc, counters, end


def _render_chunk(ctx, region, ci, start, end, should_cancel, dims, buffers=None):
    """Camera samples [start, end) of the region (sample = pixel * spp + sub-sample):
    returns their sums over the pixels they touch, the ray counters, and `end`.
    buffers: the calling thread's BounceBuffers (None: the chunk's own)."""
    s = ctx.settings
    x0, y0, x1, y1 = region
    rw = x1 - x0
    spp = s.spp
    m = max(1, int(math.sqrt(spp)))
    cells = m * m
    full_rounds = (spp // cells) * cells
    jitter_order = np.random.default_rng(0x5EED).permutation(cells)  # (int64)
    rng = np.random.default_rng([s.seed, 7, ci])
    n = end - start
    counters = Counters()
    # Pixel jitter: stratified over the same m x m grid, but visited in a scrambled
    # order. With the plain order, jitter cell and light / gather cells were paired
    # by a fixed offset, so a pixel split by an edge saw only part of the gather
    # hemisphere on each side (a dashed line along a floor-wall seam, measured).
    # (Each generator call draws its numbers in order: one call of 2 n numbers gives the
    # two calls of n that this stream was made with.)
    jitter = rng.random((2, n))
    pix, sub, px, py = (np.empty(n, np.int64) for _ in range(4))
    jx, jy = np.empty(n), np.empty(n)
    chunk_samples(start, spp, m, jitter_order, jitter, rw, x0, y0, pix, sub, px, py, jx, jy)
    acc = Accumulator(int(pix[-1] - pix[0]) + 1, int(pix[0]))
    if full_rounds < spp:
        rest = sub >= full_rounds  # beyond whole rounds of the grid: uniform
        n_rest = int(np.count_nonzero(rest))
        if n_rest:
            jx[rest], jy[rest] = rng.random((2, n_rest))
    _trace_camera_samples(ctx, acc, pix, px, py, jx, jy, sub, pix, spp, rng, dims, s.seed,
                          np.random.default_rng([s.seed, 11, ci]), counters, should_cancel,
                          buffers or BounceBuffers())
    return acc, counters, end


def _trace_camera_samples(ctx, acc, rows, px, py, jx, jy, sub, pix, spp, rng, dims, salt,
                          path_rng, counters, should_cancel, buffers):
    """Camera rays through pixels (px, py) (N,) at their jitter (jx, jy) (N,) in [0,1),
    traced and summed into acc's rows (N,): sub (N,) each sample's index among the spp
    samples its pixel pix (N,) takes, stratified by StratifiedSampler(salt); rng the
    chunk's stream (after the jitter), path_rng its path stream."""
    s = ctx.settings
    cam = ctx.scene.camera
    # The stratified numbers become positions by the pixel filter's distribution (Cycles
    # samples its filter by importance: every ray weight 1; engine/pixelfilter.py).
    sampler = StratifiedSampler(sub, pix, spp, rng, dims, salt=salt)
    # The lens point: a sampler dimension of its own (("lens",), allocated only with depth
    # of field, so pinhole renders keep their dimensions and streams), stratified over
    # the pixel's samples as Cycles' PRNG_LENS dimension.
    lens = sampler.uv(("lens",)) if cam.has_dof else None
    o, d, tmax = camera_rays(cam, ctx.geo.offset, ctx.scene.width, ctx.scene.height, px, py,
                             jx, jy, filter_table(s.pixel_filter, s.filter_width), lens)
    counters.camera_rays += len(o)
    tp = np.ones((len(o), 3))
    if cam.panorama is not None:
        tp[tmax <= 0.0] = 0.0  # outside a fisheye's circle: no light (Cycles' tmax 0)
    forward = -cam.rotation[:, 2]
    cam_pos = cam.position - ctx.geo.offset
    _trace_paths(ctx, acc, o, d, tmax, tp, rows, rng, counters, cam_pos, forward,
                 should_cancel, sampler, sub, path_rng, buffers)


def _write_film(film, acc, spp, rh, rw, want=()):
    """acc's sums over spp samples (a number, or (npix,1) per pixel: adaptive) into film;
    want: RenderSettings.data_passes (each asked for is written, zero sums if none came)."""
    inv = 1.0 / spp
    inv1 = inv[:, 0] if np.ndim(inv) else inv  # (for the scalar passes)
    for name in Accumulator.NAMES:
        getattr(film, name)[...] = (acc.buf[name] * inv).reshape(rh, rw, 3).astype(np.float32)
    film.alpha[...] = (acc.alpha * inv1).reshape(rh, rw)
    film.holdout[...] = (acc.holdout * inv1).reshape(rh, rw)
    with np.errstate(invalid="ignore", divide="ignore"):
        depth = np.where(acc.depth > 0.0, acc.depth, np.inf)
        nrm = acc.normal / np.maximum(np.linalg.norm(acc.normal, axis=1), 1e-300)[:, None]
    film.depth[...] = depth.reshape(rh, rw)
    film.normal[...] = nrm.reshape(rh, rw, 3)
    for _name, key, ch in datapasses.keys(want):  # a pass no sample wrote: its zero sums
        if key not in acc.data:
            acc.data[key] = np.zeros((acc.npix, 3) if ch == 3 else acc.npix)
    for key, total in acc.data.items():  # per-sample averages (Cycles' render buffer)
        per = inv if total.ndim == 2 else inv1
        film.data[key] = datapasses.film_value(key, total, per).reshape(
            (rh, rw) + total.shape[1:]).astype(np.float32)
    if acc.catcher is not None:  # per-sample averages too (engine/shadowcatcher.py)
        film.catcher = {key: (total * (inv if total.ndim == 2 else inv1)).reshape(
            (rh, rw) + total.shape[1:]) for key, total in acc.catcher.items()}


class BounceBuffers:
    """The arrays camerakernels.shade_lobes writes per bounce (packed lobes, lobe choice,
    the rows to shade and their diffuse albedo) and the direct-light stage's
    (directlight.DirectLightBuffers), kept by one thread between its bounces and chunks:
    fresh arrays of tens of MB per bounce cost more in first-touch page faults than the
    kernels' own work (docs/performance.md, "Ninth slice"). A bounce's hits read them
    until its continuation is made, before the next bounce writes."""

    def __init__(self):
        self.size = -1  # (-1: a first call for 0 rows still makes its empty arrays)
        self.direct = DirectLightBuffers()
        self.paths = 0  # rows of the path-state arrays (paths_start)

    def paths_start(self, n):
        """(travelled (n,), org_ns (n,3), org_p (n,3), chain (n,3) int64): zeros, the
        path state _trace_paths starts a chunk with. Kept by the thread between its
        chunks: a fresh np.zeros of them on a worker thread (its own malloc arena) is
        memset page by page, ~10 MB a chunk of first-touch faults (docs/performance.md,
        "Seventeenth slice"). Zeroed once, not refilled: _trace_paths only reads them and
        replaces them before it writes (keep_path_hits, np.take, chain[keep]; ~10 MB of
        memset a 131,072-sample chunk saved, docs/performance.md "fig8speed"); a render's
        buffers are checked to stay zero by tests/test_camera_glass.py."""
        if n > self.paths:
            self.paths = n
            self.travelled = np.zeros(n)
            self.org_ns, self.org_p = np.zeros((n, 3)), np.zeros((n, 3))
            self.chain = np.zeros((n, 3), np.int64)
        return self.travelled[:n], self.org_ns[:n], self.org_p[:n], self.chain[:n]

    def take(self, n):
        """(prm (n, N_PACK), sel (n, N_LOBES), p (n, N_LOBES - 1), q (n,), psum (n,),
        glossy (n,) bool, rows (n,) int64, wd (n, 3)): unwritten rows."""
        if n > self.size:
            self.size = n
            self.prm = np.empty((n, pr.N_PACK))
            self.sel = np.empty((n, pr.N_LOBES))
            self.p = np.empty((n, pr.N_LOBES - 1))
            self.q, self.psum = np.empty(n), np.empty(n)
            self.glossy = np.empty(n, np.bool_)
            self.rows = np.empty(n, np.int64)
            self.wd = np.empty((n, 3))
        return (self.prm[:n], self.sel[:n], self.p[:n], self.q[:n], self.psum[:n],
                self.glossy[:n], self.rows[:n], self.wd[:n])


def _transmitting(params) -> np.ndarray:
    """(M,) bool per row of closure parameters (M, N_MAT): a glass or translucent lobe
    (light sampling through the surface may apply: engine/glasslight.py)."""
    return (params[:, pr.M_TRANS] > 0) | (params[:, pr.M_TL] > 0)


def _chain_counts(chain):
    """(K,4) int64 camera-side counts in B_TOTAL order (total, diffuse, glossy,
    transmission) from the camera chain's (K,3) (total, glossy, transmission): its
    other bounces are sheen's, diffuse in Cycles' count (engine/chaincounts.py)."""
    chain = np.asarray(chain, np.int64)
    return np.stack([chain[:, 0], chain[:, 0] - chain[:, 1] - chain[:, 2], chain[:, 1],
                     chain[:, 2]], axis=1)


def _trace_paths(ctx, acc, o, d, tmax, tp, pix, rng, counters, cam_pos, forward,
                 should_cancel, sampler=None, sample_id=None, bsdf_rng=None, buffers=None,
                 split_catchers=True):
    # split_catchers: camera rays whose first hit is a shadow catcher are traced on by a
    # call of their own into acc's catcher sums (_split_catcher_paths); False in that call.
    buffers = buffers or BounceBuffers()
    s = ctx.settings
    depth_limit = ctx.plan.specular_depth
    # The camera sampler as it came (the scattering media's distances take its
    # ("volume",) dimension at every bounce, by each path's pixel and sample index).
    sampler0 = sampler
    pix_shift = (int(sampler.pix[0]) - int(pix[0])) if sampler is not None and len(pix) else 0
    # A pixel's radius on the surface it sees: half a pixel's width at the distance the
    # path has travelled (orthographic: the pixel's half width).
    cam = ctx.scene.camera
    hw, _ = cam.half_extents(ctx.scene.width, ctx.scene.height)
    pixel = 2.0 * hw / ctx.scene.width
    ortho = cam.kind == "ORTHO"
    # The zeros the path state starts from (travelled, the shading normal and point where
    # each path left: the world's MIS pdf, the light tree's choice; the chain's bounces),
    # from the thread's buffers; replaced, never written in place (paths_start).
    travelled, org_ns, org_p, chain = buffers.paths_start(len(o))
    # Each path's camera ray differential (Cycles keeps the camera's dD through every
    # bounce): Bump nodes take their differences over dD x travelled (engine/bump.py),
    # plus the footprint at the ray's origin: Cycles starts a camera ray at its clip
    # start with dP = nearclip x dD (kernel/camera/camera.h; 0.1 m from a 16 mm lens in
    # a 2 m room is 10 % of the first hit's footprint).
    cam_dd = camera_differential(cam, ctx.scene.width, ctx.scene.height, d)
    cam_dp0 = (None if ortho else
               cam_dd * np.linalg.norm(o - np.asarray(cam_pos, np.float64), axis=1))
    ray_cls = np.full(len(o), CAMERA, np.int64)  # camera rays until a glossy / refraction
    pdf_b = np.full(len(o), np.inf)  # pdf of the continuation that made each ray (MIS)
    modes = light_modes(ctx)
    # Lamps the rough reflective lobes alone sample (Diffuse visibility off): MIS for the
    # glossy rays that meet them (lamp_mis).
    refl_only = reflection_only_lights(ctx)
    # Lamps through shades (engine/shadelight.py): the glossy lobes' shade samples and
    # the continuation that meets the shade share the light by MIS. shade_from: the
    # paths whose ray left a hit whose glossy lobes took the shade samples, by a
    # reflection (None: none); lamp_w (N, L): the weight of each light's emission the
    # path's ray may meet (set after a shade hit those paths met; None: 1).
    shades = shades_for(ctx)
    shade_from = lamp_w = None
    world = [li for li, light in enumerate(ctx.lights)
             if light.kind == WORLD and modes[li] == MODE_MIS]
    # (objects' holdout, and materials' that camera rays see: a Holdout shader chosen by
    # Light Path's Is Camera Ray, engine/raymaterials.py)
    mat_holdout = ctx.table.holdout if (ctx.table.holdout is not None
                                        and ctx.table.holdout.any()) else None
    has_holdout = bool(ctx.geo.holdout.any()) or mat_holdout is not None
    # (O,) bool: the shadow catcher objects (None: none; engine/shadowcatcher.py).
    catchers = getattr(ctx, "catcher_objects", None)
    # No material emits: no emission rows to gather or test (surface_hit's are zeros).
    emitters = bool(ctx.table.emission.any())
    want_glossy = bool(np.any(modes != MODE_CONTINUATION) or refl_only.any())
    table_alpha = np.ascontiguousarray(ctx.table.alpha, np.float64)
    plain = plain_surfaces(ctx.table)  # no per-hit nodes: surface data and lobes fused
    bumped = reads_footprint(ctx.table)  # (the gathers carry footprints for Bump nodes)
    # Smooth glass bent past photonkernels.GLASS_ADJOINT_MIN_BEND_DEG (None: none).
    turned_refl = TurnedReflections.for_context(ctx)
    aniso_on = bool(anisotropic_materials(ctx.table.closure_params).any())
    cam_pos = np.ascontiguousarray(cam_pos, np.float64)  # (view_depth's signature)
    forward = np.ascontiguousarray(forward, np.float64)
    c = np.ascontiguousarray
    # Flat passages through thin glass (engine/shadowtransmittance.py): None without them.
    passages = CameraPassages.for_context(ctx, len(o))
    # Absorbing media inside objects (engine/media.py; NO_SIGMA: none, nothing done), and
    # the medium each path is in (-1: none known; a camera inside one: the local rule).
    sigma = media.absorption_table(ctx.table)
    medium = None
    # The world volume's row (engine/worldmedium.py; -1: none): the medium outside every
    # object's, where the paths start and where they return leaving an object's medium.
    world_row = worldmedium.medium_row(ctx)
    if sigma.shape[0]:
        # A camera inside a medium object (a fog cube around the scene) starts its paths
        # in it (engine/mediumstart.py; an orthographic camera's rays start apart: -1).
        medium = np.full(len(o), world_row if ortho else
                         point_medium(ctx, cam_pos, sigma, outside=world_row), np.int64)
    # Light scattered towards the camera inside scattering media (engine/volumescatter.py;
    # None: no material scatters), from its own stream of numbers (made when first needed).
    scatter = volumewalk.WalkingScattering.for_context(ctx) if medium is not None else None
    # Emitting media (engine/volumeemission.py; None: none emits): every segment in one
    # adds its glow, weighted by the throughput at the segment's start.
    glow = volumeemission.MediumEmission.for_context(ctx) if medium is not None else None
    vol_rng = None
    # Cycles' bounce limits on the camera chain (docs/design.md, Bounce limits): each
    # path's glossy / transmission bounces so far and their total; a path past a limit
    # still collects emission and the background where its ray ends (Cycles'
    # PATH_RAY_TERMINATE_AFTER_TRANSPARENT), but that hit is neither shaded nor continued.
    limits = s.bounce_limits
    # Cycles' Light Paths > Max Bounces > Transparent, counted along the whole path
    # (path_state_next: every transparent pass adds one to transparent_bounce, no bounce
    # resets it; docs/design.md, Transparent shadows): each path's passes so far. Once a
    # pass brings it to the limit, the next surface ends the path (Cycles'
    # PATH_RAY_TERMINATE_ON_NEXT_SURFACE: its emission is still collected, and the world
    # where the ray misses; integrate_surface_terminate), and a hit's shadow rays cross
    # only the passes left. A volume-only surface's pass is none (path_state_volume_next).
    t_limit = max(int(s.transparent_max_bounces), 1)
    t_count = np.zeros(len(o), np.int64)
    volume_only = (np.asarray(ctx.table.volume_only, bool)
                   if getattr(ctx.table, "volume_only", None) is not None
                   and np.any(ctx.table.volume_only) else None)
    # Cycles' Clamp Direct / Indirect (engine/sampleclamp.py): off, nothing is touched.
    # Cycles' bounce of a contribution is the chain's bent bounces (chain[:, 0]) for light
    # sampled at a hit, one less for an emitter or the world the ray meets; 0 is direct.
    clamping = sampleclamp.enabled(s)
    # Each path's clamp scale (sampleclamp.split_throughput): the product of the Cycles
    # probabilities of the glass halves it took where a glass lobe split (None: 1 for
    # every path, no split yet; only while clamping).
    cscale = None
    # Each path's glass hits left to split (SPLIT_GLASS_HITS; None: the lobe choice
    # everywhere).
    may_split = (np.full(len(o), SPLIT_GLASS_HITS, np.int64)
                 if SPLIT_GLASS_HITS > 0 else None)
    # Cycles' Filter Glossy (engine/filterglossy.py; None: 0, nothing blurs): each path's
    # min_ray_pdf, and from it the blur of the microfacet lobes at its next hit.
    fgblur = PathBlur.for_settings(s, len(o))
    # Materials with a glass or translucent lobe (the rows whose packed lobes glasslight
    # reads; a diffuse-only hit's are left unwritten by shade_lobes).
    glass_mat = _transmitting(np.asarray(ctx.table.closure_params))
    glass_rng = None  # glasslight's numbers, made when first needed
    # Random-walk subsurface scattering (engine/subsurfacewalk.py; None: nothing walks).
    sss = subsurfacewalk.SubsurfaceWalks.for_context(ctx)
    sss_rng = None
    # Surfaces touching a glass face (engine/coincident.py; None: no glass touches
    # anything), and the triangle each path left (-1: the camera) while there are.
    # (org_p is not that point after a flat passage: CameraPassages gives it the point
    # before the glass, for MIS.)
    coincident = CoincidentSurfaces.for_context(ctx) if glass_mat.any() else None
    org_prim = np.full(len(o), -1, np.int64) if coincident is not None else None
    # Light Linking (engine/lightlinking.py): the triangle each path last left (-1: the
    # camera), whose object a lamp it meets must light (Cycles' mis_ray_object).
    links = getattr(ctx, "links", None)
    link_prim = np.full(len(o), -1, np.int64) if links is not None else None
    left_p = None  # the point each path left (its previous hit), while coincident
    # Cycles' data passes (engine/datapasses.py): the paths still carrying denoising
    # features; the camera's axes as rows (Cycles' worldtocamera for directions).
    want_data = datapasses.wanted(s)
    feat = np.ones(len(o), bool) if "denoising" in want_data else None
    ftp = np.ones((len(o), 3)) if feat is not None else None
    to_camera = None
    if want_data:
        # A panorama's camera space is its frame's (Cycles: tfm times the frame matrix).
        to_camera = ((cam.rotation @ cam.panorama.frame).T if cam.panorama is not None else
                     np.stack([cam.rotation[:, 0], cam.rotation[:, 1], -cam.rotation[:, 2]]))
    # The depth and surface data passes (datapasses.add_surface): each path's "single
    # pass" done, and whether it is its pixel's first sample (the first adaptive round's
    # sample 0), whose surface writes them as Cycles' sample 0 does.
    single = np.zeros(len(o), bool)
    # The Vector pass' motion (engine/vectorpass.py), the Ambient Occlusion pass.
    motion = vectorpass.for_context(ctx) if "vector" in want_data else None
    want_ao = "ao" in want_data
    # Cycles' light passes (engine/lightpasses.py): each path's class and bends.
    lpass = acc.light = (lightpasses.PathPasses(acc, len(o)) if "light" in want_data
                         else None)
    # A constant world through the first hits' reflective lobes, its escaping part shared
    # with further reflections (probed_world; None: not here); world_share (N,): the
    # world's weight where the continued rays escape (None: 1).
    probe_world = (probed_world(ctx, modes, clamping, medium, world_row, links, catchers)
                   if depth_limit > 0 else None)
    world_share = None
    probe_rng = None  # world_probes' numbers, made when first needed
    first = ((np.asarray(sample_id) == 0) if getattr(ctx, "camera_round_index", 0) == 0
             else np.zeros(len(o), bool))
    for bounce in range(depth_limit + 1):
        if len(o) == 0:
            return
        if should_cancel is not None and bounce > 0 and should_cancel():
            raise Cancelled()
        target = "emission" if bounce == 0 else "specular"
        counters.count("paths", bounce, len(o))
        t, prim, u, v = ctx.accel.intersect(o, d, tmax, cls=ray_cls)
        if bounce > 0 and coincident is not None:
            # Rays leaving a glass face that another surface touches (a bottle standing
            # on the floor) outwards or into the glass, or that surface into the glass,
            # meet the other one there, as in Cycles; rays inside the glass reaching the
            # floor under it leave the glass first (engine/coincident.py).
            coincident.meet(o, d, left_p, org_prim, t, prim, u, v, inward=True)
        # Light surfaces, seen by the ray kinds the light is visible to (Light.ray_kinds:
        # by default not camera rays, but mirrors and glass). A lamp is transparent, as
        # in Cycles (integrator_shade_light_forward: its light added, the ray goes on
        # from it as a transparent bounce): the ray goes on to the surface or world
        # behind it, unless the pass reaches Max Bounces > Transparent (lamp_passes).
        # (Ending there lost the world behind an area light in a smooth coat's
        # reflection: the donut's mug under a 0.001 W lamp, docs/accuracy.md "mis51".)
        linking = link_prim is not None and bounce > 0
        met_lamps, linked = lamps_met(ctx, o, d, t, ray_cls, link_prim if linking else None,
                                      ray_cls == CAMERA)
        for li, light, rows, tl, L in linked:
            _add_lamp_light(ctx, li, light, rows, L, o, d, tl,
                            lamp_mis(modes, refl_only, li, ray_cls), passages, pdf_b,
                            org_ns, org_p, link_prim, lamp_w, clamping, tp, chain, s, acc,
                            target, pix, ftp, feat, sampleclamp.split_throughput(tp, cscale))
        t_end = None
        if met_lamps:
            t_end, t_count = lamp_passes(met_lamps, len(o), t_count, t_limit)
        for li, light, rows, tl_rows, L in met_lamps:
            if t_end is not None:
                # (past the pass that ended the path: not met)
                keep_r = tl_rows <= np.take(t_end, rows)
                rows, tl_rows, L = rows[keep_r], tl_rows[keep_r], L[keep_r]
            if len(rows):
                tl = np.full(len(o), np.inf)
                tl[rows] = tl_rows
                if medium is not None and len(rows):
                    # The lamp seen through the medium the ray is in (an object's, the
                    # world volume's): the segment's exp(-sigma_t s). (A medium not
                    # known, -1: none on the way as far as the path knows.)
                    m_rows = np.take(medium, rows)
                    seg = (np.take(tl, rows) * np.linalg.norm(np.take(d, rows, axis=0),
                                                              axis=1))
                    L = L * np.where((m_rows >= 0)[:, None],
                                     np.exp(-np.take(sigma, np.maximum(m_rows, 0), axis=0)
                                            * seg[:, None]), 1.0)
                # (MIS for the rays that met the light only: with the light tree each
                # takes a walk down the tree per light for its choice probability)
                _add_lamp_light(ctx, li, light, rows, L, o, d, tl,
                                (lamp_mis(modes, refl_only, li, ray_cls)
                                 if bounce > 0 and len(rows) > 0 else False),
                                passages, pdf_b, org_ns, org_p, link_prim, lamp_w, clamping,
                                tp, chain, s, acc, target, pix, ftp, feat,
                                sampleclamp.split_throughput(tp, cscale))
        if t_end is not None:
            # Paths whose lamp pass reached the transparent limit end at that lamp.
            ended_at = np.isfinite(t_end)
            t = np.where(ended_at, t_end, t)
            prim = np.where(ended_at, -2, prim)
        miss = prim == -1
        if glow is not None:
            # The glow along the segments that end on a lamp, or escape through the world
            # volume (its length until the transmittance is 1e-13: e / sigma_t).
            _glow_without_hit(ctx, glow, acc, target, pix, prim, o, d, t, tp, medium,
                              world_row)
        if link_prim is not None and bounce > 0 and links.shadow_groups:
            # Shadow Linking: a shadow-linked sun seen past its non-blockers by the rays
            # that left a surface and met one (the rays that missed see it below).
            _shadow_linked_suns(ctx, links, o, d, ~miss & (ray_cls != CAMERA), link_prim,
                                modes, pdf_b, org_ns, org_p, clamping, tp, chain, acc,
                                target, pix, ftp, feat, s,
                                sampleclamp.split_throughput(tp, cscale), refl_only, ray_cls)
        if world_row >= 0 and scatter is not None and miss.any():
            # Rays escaping into the world volume: the lamps' light it scatters along
            # their whole (infinite) length, cut where its transmittance is 1e-13
            # (engine/worldmedium.py); the world beyond sends nothing.
            esc, esc_prim, esc_t = worldmedium.escaping(ctx, prim, d, medium, world_row)
            if len(esc):
                if vol_rng is None:
                    vol_rng = (bsdf_rng.spawn(1)[0] if bsdf_rng is not None
                               else np.random.default_rng(rng.integers(1 << 62)))
                esc_uv = None
                if (sampler0 is not None and sample_id is not None
                        and volumescatter.STRATIFIED):
                    esc_uv = sampler0.for_samples(
                        np.asarray(sample_id)[esc], np.asarray(pix)[esc] + pix_shift).uv(
                        ("volume",), rng=vol_rng)
                src, Ls = scatter.radiance(esc_prim, np.take(o, esc, axis=0),
                                           np.take(d, esc, axis=0), esc_t,
                                           np.take(medium, esc), vol_rng, counters, esc_uv)
                if len(src):
                    rows = esc[src]
                    acc.add("direct" if bounce == 0 else "specular", pix, Ls, tp, rows)
                    if lpass is not None:
                        lpass.volume(pix, Ls, tp, rows)
        if miss.any():
            drawn = miss
            if s.film_transparent:
                # Cycles' transparent background (PATH_RAY_TRANSPARENT_BACKGROUND): camera
                # rays, and those continued through transparent surfaces (still CAMERA),
                # see no world. Past the first bounce they give back the coverage their
                # first hit counted, by their throughput's mean (film_write_transparent:
                # average(throughput)): an alpha-0.4 card over nothing has alpha 0.4.
                through = miss & (ray_cls == CAMERA)
                if bounce > 0 and through.any() and world_row < 0:
                    # (in a world volume they reach the world with throughput 0)
                    rows = np.nonzero(through)[0]
                    acc.add_scalar(acc.alpha, np.take(pix, rows),
                                   -np.take(tp, rows, axis=0).mean(axis=1))
                drawn = miss & ~through
            if drawn.any():
                # (The rows by np.take: a boolean mask gathers (N,3) rows ~2x slower.)
                missed = np.nonzero(drawn)[0]
                d_miss = np.take(d, missed, axis=0)
                # (black beyond a world volume: engine/worldmedium.py; camera rays see
                # the camera world where the world has one: Is Camera Ray)
                missed_camera = np.take(np.broadcast_to(ray_cls, (len(o),)), missed) == CAMERA
                radiance = worldmedium.background(
                    ctx.scene, d_miss,
                    missed_camera if worldmedium.has_camera_world(ctx.scene) else None)
                if bounce > 0 and world:
                    li = world[0]
                    radiance = radiance * _mis_weight(ctx, li, ctx.lights[li],
                                                      np.take(o, missed, axis=0), d_miss,
                                                      None, pdf_b[missed],
                                                      np.take(org_ns, missed, axis=0),
                                                      np.take(org_p, missed, axis=0),
                                                      _link_sets(ctx, link_prim,
                                                                 missed))[:, None]
                full = None
                if world_share is not None:
                    # Reflections of the first hits that probes share (world_probes): their
                    # share of the world's light; the data passes keep it whole.
                    full = radiance
                    radiance = radiance * np.take(world_share, missed)[:, None]
                env = radiance  # (the world's part; the suns' discs are added below)
                for li, light in enumerate(ctx.lights):
                    # A sun's disc is seen by camera rays only when its light is visible
                    # to them: a Sky Texture's disc (the background); the add-on exports
                    # sun lamps invisible to the camera, as Cycles shows them. Past bounce
                    # 0 every disc is seen.
                    if bounce > 0 or light.ray_kinds & CAMERA:
                        sun = light.seen_at_infinity(d_miss)
                        if sun is not None and link_prim is not None and bounce > 0:
                            seen = missed_camera | links.lights_hit(
                                li, ctx.geo, np.take(link_prim, missed))
                            sun = sun * seen[:, None]
                        if sun is not None:
                            sun_mis = (lamp_mis(modes, refl_only, li, ray_cls)
                                       if bounce > 0 else False)
                            if sun_mis is not False:
                                w = _mis_weight(ctx, li, light, np.take(o, missed, axis=0),
                                                d_miss, None, pdf_b[missed],
                                                np.take(org_ns, missed, axis=0),
                                                np.take(org_p, missed, axis=0),
                                                _link_sets(ctx, link_prim, missed))
                                if sun_mis is not True:  # (the glossy rays alone)
                                    w = np.where(np.take(np.broadcast_to(
                                        sun_mis, (len(o),)), missed), w, 1.0)
                                sun = sun * w[:, None]
                            radiance = radiance + sun
                            if full is not None:
                                full = full + sun
                raw = radiance
                if clamping:
                    radiance = sampleclamp.clamp(
                        radiance, sampleclamp.split_throughput(tp, cscale), missed,
                        sampleclamp.bounce_limits(s, np.take(chain[:, 0], missed) - 1))
                acc.add(target, pix, radiance, tp, missed)
                datapasses.add_light(acc, pix, missed, tp, ftp, feat,
                                     radiance if full is None else full)
                if lpass is not None:
                    # The world into Environment, the suns' discs into Emission (Cycles'
                    # distant lights), a clamp shared in proportion.
                    env, sun_part = lightpasses.split_direct(
                        raw, None if env is raw else raw - env,
                        radiance if clamping else None)
                    lpass.met(pix, env, tp, missed, lightpasses.ENVIRONMENT)
                    if sun_part is not None:
                        lpass.met(pix, sun_part, tp, missed, lightpasses.EMISSION)
            datapasses.add_background(acc, want_data, pix,
                                      np.nonzero(miss & (ray_cls == CAMERA))[0], first, single)
        hitm = prim >= 0
        if has_holdout and hitm.any():
            # Camera rays that meet a holdout surface see a hole: no colour, alpha 0.
            hole = np.zeros(len(prim), bool)
            hole[hitm] = np.take(ctx.geo.holdout, prim[hitm]) & (ray_cls[hitm] == CAMERA)
            if mat_holdout is not None:
                rows_h = raymaterials.hit_materials(ctx.geo, ctx.table, prim[hitm],
                                                    ray_cls[hitm])
                hole[hitm] |= mat_holdout[rows_h] & (ray_cls[hitm] == CAMERA)
            if hole.any():
                prim = np.where(hole, -3, prim)
                hitm &= ~hole
                # By the throughput's mean (1 at the first hit; a holdout behind an
                # alpha-0.4 card holds out 0.6: Cycles' average(throughput)); past the
                # first bounce the coverage the first hit counted is given back too.
                held = np.take(tp, np.nonzero(hole)[0], axis=0).mean(axis=1)
                acc.add_scalar(acc.holdout, pix[hole], held)
                if bounce > 0:
                    acc.add_scalar(acc.alpha, pix[hole], -held)
        if split_catchers and catchers is not None:
            # Camera rays meeting a shadow catcher.
            caught = np.zeros(len(prim), bool)
            if hitm.any():
                caught[hitm] = np.take(catchers, np.take(ctx.geo.object_id, prim[hitm])) & (
                    ray_cls[hitm] == CAMERA)
            if bounce > 0:
                # Continued through a transparent surface: not split (Cycles splits it
                # there too), counted for a warning (render_pass).
                if caught.any():
                    counters.count("catcher behind transparent", bounce, int(caught.sum()))
            elif caught.any() or not s.film_transparent:
                # First: Cycles' split (integrator/shadow_catcher.h): their light is the
                # catcher's "with the objects" radiance, kept apart
                # (engine/shadowcatcher.py); they leave this batch.
                _split_catcher_paths(ctx, acc, caught, miss, o, d, tmax, tp, pix, rng,
                                     counters, cam_pos, forward, should_cancel, sampler,
                                     sample_id, bsdf_rng, buffers)
                prim = np.where(caught, -3, prim)
                hitm &= ~caught
        if bounce == 0:
            # (in a world volume every camera ray's throughput reaches 0 before the world:
            # opaque, as Cycles' average(throughput) at the background)
            acc.add_scalar(acc.alpha, pix, ((prim >= 0) | (prim == -2) | (world_row >= 0))
                           .astype(float))
        if not hitm.any():
            return
        if hitm.all():  # every path met a surface (a closed room): nothing to compact
            kept = None
            travelled = travelled + t
        else:
            # The paths that met a surface, compacted (camerakernels.keep_path_hits).
            kept, o, d, tp, pix, prim, u, v, t, sample_id, travelled, ray_cls, pdf_b = (
                keep_path_hits(prim, o, d, tp, pix, u, v, t, sample_id, travelled, ray_cls,
                               pdf_b))
            cam_dd = np.take(cam_dd, kept)
            if cam_dp0 is not None:
                cam_dp0 = np.take(cam_dp0, kept)
            if passages is not None:
                passages.compact(kept)
            if lpass is not None:
                lpass.take(kept)
            chain = np.take(chain, kept, axis=0)
            t_count = np.take(t_count, kept)
            if shade_from is not None:
                shade_from = shade_from[kept]
            if may_split is not None:
                may_split = may_split[kept]
            if cscale is not None:
                cscale = cscale[kept]
            if fgblur is not None:
                fgblur.take(kept)
            if feat is not None:
                feat, ftp = feat[kept], ftp[kept]
            single, first = single[kept], first[kept]
        if sampler is not None and bounce == 0 and kept is not None:
            sampler = sampler.subset(kept)
        if medium is not None:
            # A path that travelled inside an absorbing object's medium keeps
            # exp(-sigma_a s) of its throughput over the segment, before this hit is
            # shaded and continued (engine/media.py).
            if kept is not None:
                medium = medium[kept]
            tp_seg = tp  # (attenuated returns a new array when it dims any row)
            tp = media.attenuated(ctx.geo, sigma, prim, d, t, tp, medium)
            tp = heterogeneous.attenuated(ctx, tp, o, d, t, prim)  # (density textures)
            if glow is not None:
                # The glow of an emitting medium along the segment (engine/volumeemission.py).
                src, Le = glow.along(prim, d, t, medium, o=o)
                if len(src):
                    acc.add(target, pix, Le, tp_seg, src)
                    if lpass is not None:
                        lpass.met(pix, Le, tp_seg, src, lightpasses.EMISSION)
            if scatter is not None:
                # The light the medium scatters into the segment (single scattering of
                # the lamps' light, weighted by the throughput at its start).
                if vol_rng is None:
                    # A child of bsdf_rng's stream (left as it was), as glass_rng.
                    vol_rng = (bsdf_rng.spawn(1)[0] if bsdf_rng is not None
                               else np.random.default_rng(rng.integers(1 << 62)))
                # The camera segments' distances (and strategy choices) stratified over
                # the pixel's samples (the ("volume",) dimension), as Cycles' QMC
                # numbers: fog37, the god ray's noise.
                vol_uv = None
                if (sampler0 is not None and sample_id is not None
                        and volumescatter.STRATIFIED):
                    # (a transparent surface's continuation, the fog box's invisible
                    # front face, makes its segments bounce 1: the sampler's rows are
                    # rebuilt from the paths' own sample indices and pixels)
                    vol_uv = sampler0.for_samples(sample_id, np.asarray(pix) + pix_shift).uv(
                        ("volume",), rng=vol_rng)
                if lpass is None:
                    scatter.add(acc, "direct" if bounce == 0 else "specular", pix, prim, o,
                                d, t, medium, tp_seg, vol_rng, counters, uv=vol_uv)
                else:  # (scatter.add's two steps, the light also into the light passes)
                    src, Ls = scatter.radiance(prim, o, d, t, medium, vol_rng, counters,
                                               vol_uv)
                    if len(src):
                        tp_c = np.ascontiguousarray(tp_seg, np.float64)
                        acc.add("direct" if bounce == 0 else "specular", pix, Ls, tp_c, src)
                        lpass.volume(pix, Ls, tp_c, src)
        # (Sheen's bounces, continued as DIFFUSE rays, are the total's others: Cycles
        # counts them as diffuse.)
        over = ((chain[:, 0] > limits[0]) | (chain[:, 1] > limits[2])
                | (chain[:, 2] > limits[3])
                | (chain[:, 0] - chain[:, 1] - chain[:, 2] > limits[1])) if bounce > 0 else None
        if over is not None and not over.any():
            over = None
        # Paths whose last pass reached the transparent limit end at this hit: neither
        # shaded nor continued, not even through its transparent share (unlike a bounce
        # limit's PATH_RAY_TERMINATE_AFTER_TRANSPARENT).
        ended = t_count >= t_limit if bounce > 0 else None
        over_pass = over  # (the bounce limits' rows that still pass a transparent share)
        if ended is not None and ended.any():
            if over is not None:
                over_pass = over & ~ended
            over = ended if over is None else over | ended
        # A pixel's footprint: only the photon estimates read it.
        footprint = None
        if s.photon_mapping:
            footprint = np.full(len(t), 0.5 * pixel) if ortho else 0.5 * pixel * travelled
        n = len(prim)
        # The lobes, the continuation's choice, the glossy rows and the rows to shade
        # (camerakernels.shade_lobes: rows nothing reads stay unwritten); without per-hit
        # nodes with the surface data in the same kernel (bsdf.surface_hit_lobes).
        bufs = buffers.take(n)
        prm, sel, p, q, psum, glossy, dsel, wd = bufs
        # The material each ray class meets (Light Path in a material: camera rays and
        # the chain's glossy / transmission rays may meet a variant; engine/raymaterials.py;
        # None: every hit its triangle's own).
        cls_mat = raymaterials.path_materials(ctx.geo, ctx.table, prim, ray_cls)
        # Hits on smooth glass bent past the photons' adjoint threshold keep their shading
        # normal where it puts the viewer below it: Cycles turns it (principled.
        # glossy_normals), as the gather chains do (engine/turnedlight.py).
        unguarded = (None if turned_refl is None
                     else turned_refl.camera_unguarded(ctx.geo, prim, u, v, cls_mat))
        # So do glossy-only hits (metal), where the guard would replace their normal
        # (engine/turnedglossy.py, glossyguard45).
        glossy_kept = turnedglossy.camera_unguarded(ctx.geo, ctx.table, prim, u, v, d, cls_mat)
        if glossy_kept is not None:
            unguarded = glossy_kept if unguarded is None else unguarded | glossy_kept
        # The Filter Glossy alpha of each hit (None: none blurs; a camera ray's first hit
        # never does): the microfacet lobes widened after their set-up, so a blurred mirror
        # or smooth glass is a rough lobe from here on (light sampling, a finite pdf).
        blur = None
        if fgblur is not None and bounce > 0:
            blur = fgblur.blur()
            blur = blur if len(blur) else None
        # The path's ray footprint at its hits (Cycles' sd->dP: the camera's dD x the
        # distance from the camera; orthographic, the pixel's width), for Bump nodes.
        cam_fp = cam_dd if ortho else cam_dp0 + cam_dd * travelled
        if plain and unguarded is None:
            hit, nd = surface_hit_lobes(ctx.geo, ctx.table, prim, u, v, d, tp, want_glossy,
                                        bufs, material=cls_mat, blur=blur,
                                        mean_weights=FIRST_HIT_MEAN_WEIGHTS and bounce == 0)
        else:
            hit = surface_hit(ctx.geo, ctx.table, prim, u, v, d, material=cls_mat,
                              unguarded=unguarded, footprint=cam_fp)
            per_hit = hit.params is not None
            nd = shade_lobes(hit.ns, hit.ng, hit.wo, hit.mat,
                             hit.params if per_hit else ctx.table.closure_params, per_hit,
                             hit.base, hit.front, table_alpha,
                             _NO_ALPHA if hit.alpha is None else c(hit.alpha, np.float64),
                             tp, want_glossy, prm, sel, q, p, psum, glossy, dsel, wd,
                             NO_BLUR if blur is None else blur,
                             FIRST_HIT_MEAN_WEIGHTS and bounce == 0)
            hit.prm = prm
        w_diffuse = None
        if fgblur is not None:
            # Each hit's diffuse lobe weight (its albedo's mean channel, Cycles' sample
            # weight; 0 on the rows not shaded): Cycles' MIS pdf of the continuation
            # counts the Lambert lobe too (filterglossy.mis_pdf).
            w_diffuse = np.zeros(n)
            if nd:
                w_diffuse[dsel[:nd]] = (wd[:nd, 0] + wd[:nd, 1] + wd[:nd, 2]) / 3.0
            # (each hit's path min_ray_pdf so far, inf at the camera's first hits: the
            # gather chains from its diffuse lobe start there, glossysplit.GatherChains)
            if bounce > 0:
                hit.min_ray_pdf = fgblur.min_pdf
        if medium is not None:
            # The medium each hit point is in: its shadow and gather rays start there
            # (directlight.direct_light's medium_sigma, gather_indirect).
            hit.medium = medium
        # The path's ray differential at the hit (Cycles' sd->dP and dD): the gather rays'
        # ends take it on over their length (bump.transfer_footprint), for Bump nodes.
        hit.footprint = cam_fp if bumped else None  # (None: nothing reads it)
        hit.spread = np.zeros(n) if ortho else cam_dd
        if aniso_on:  # the anisotropic lobes' tangents (engine/anisotropy.py)
            set_hit_tangents(ctx.geo, hit.params if hit.params is not None
                             else ctx.table.closure_params, hit, prm, u, v)
        # Hits reached through a rough lobe (a finite pdf; mirrors, glass and passes: inf):
        # one pixel's samples land all over them, so the caustic estimate's per-pixel
        # stride would only multiply its noise (issue 14's gold ball reflecting the glass
        # ball's focus: relMSE noise x3, docs/accuracy_time_principled_spheres.md).
        scattered = (np.isfinite(pdf_b) if bounce > 0 and CAUSTIC_EVERY_SAMPLE_PAST_BOUNCE
                     else None)
        if bounce == 0:
            acc.add_first_normals(pix, hit.ns, hit.front)
        if emitters:
            Le = hit.emission
            if np.any(Le > 0) and link_prim is not None and bounce > 0 \
                    and ctx.links.has_emitters:
                # An emitting object with links of its own, met from a surface it does not
                # light (camera rays and their transparent continuations see it).
                lp = link_prim if kept is None else link_prim[kept]
                Le = Le * ((ray_cls == CAMERA)
                           | ctx.links.emission_lights(ctx.geo, prim, lp))[:, None]
            if np.any(Le > 0):
                if bounce > 0:
                    op = org_p if kept is None else org_p[kept]
                    om, tm = o, t
                    if passages is not None:
                        om, tm = passages.mis_origin(np.arange(len(o)), o, d, t, op)
                    Le = Le * _mesh_mis_weight(
                        ctx, modes, prim, om, d, tm, hit.ng, pdf_b, op,
                        org_ns if kept is None else org_ns[kept],
                        _link_sets(ctx, link_prim, kept))[:, None]
                if clamping:
                    Le = sampleclamp.clamp(Le, sampleclamp.split_throughput(tp, cscale), None,
                                           sampleclamp.bounce_limits(s, chain[:, 0] - 1))
                acc.add(target, pix, Le, tp)
                if lpass is not None:
                    lpass.met(pix, Le, tp, None, lightpasses.EMISSION)
                if feat is not None:
                    datapasses.add_light(acc, pix, np.arange(len(pix)), tp, ftp, feat, Le)
        if want_data:
            # (After the emission, as Cycles; before the limits' cut: it writes these at
            # every surface it meets.)
            feat, ftp = datapasses.add_hits(acc, want_data, ctx.table, hit, pix, tp, t, feat,
                                            ftp, ray_cls == CAMERA, to_camera)
        single = datapasses.add_surface(
            acc, want_data, ctx.geo, ctx.table, hit, prim, u, v, pix, tp,
            np.nonzero(ray_cls == CAMERA)[0], first, single, cam_pos, forward, ortho,
            ctx.scene.mist, s.pass_alpha_threshold, pano=cam.panorama is not None,
            motion=motion)
        if want_ao:  # (the camera chain's surfaces: Cycles' PATH_RAY_CAMERA paths)
            # (not where the transparent limit ends the path: integrate_surface_terminate
            # comes first; the others' AO rays cross the passes left)
            aopass.add_ao(acc, ctx, hit, prim, u, v, pix, tp,
                          np.nonzero((ray_cls == CAMERA) if ended is None
                                     else (ray_cls == CAMERA) & ~ended)[0],
                          s.ao_distance, counters,
                          used=t_count if bounce > 0 and t_count.any() else None)
        # The paths from a glossy hit that took the shade samples, meeting a shade: each
        # served lamp's light through it weighted against those samples (its NEE here in
        # the glass stage, its emission met by the refraction next bounce: lamp_w).
        shade_W = None
        shade_rows = None  # (n,) the hits whose glossy lobes take the shade samples
        if shade_from is not None and shade_from.any():
            sf = np.flatnonzero(shade_from)
            op = org_p if kept is None else org_p[kept]
            on = org_ns if kept is None else org_ns[kept]
            Wsf, nr = shade_bsdf_weights(ctx, shades, op[sf], on[sf], o[sf], d[sf], t[sf],
                                         np.asarray(prim)[sf], pdf_b[sf])
            counters.shadow_rays += nr
            if (Wsf != 1.0).any():
                shade_W = np.ones((n, Wsf.shape[1]))
                shade_W[sf] = Wsf
        if bounce == 0 and MIRROR_NO_ROULETTE:
            mirror_survival(prm if hit.prm is None else hit.prm, p, psum, q, sel)
        choice = (sel, q, p, psum)
        if nd and over is not None:
            # (nd rows of dsel / wd stay in place: the shaded rows within the limits)
            shade = ~over[dsel[:nd]]
            kd = int(shade.sum())
            dsel[:kd], wd[:kd] = dsel[:nd][shade], wd[:nd][shade]
            nd = kd
        if nd:
            dsel, wd = dsel[:nd], wd[:nd]
            every = nd == n
            # Stratification pays off at the first hit; deeper hits use plain random numbers.
            strat = (None if sampler is None or bounce > 0 else
                     sampler if every else sampler.subset(dsel))
            if (strat is None and bounce > 0 and UNBENT_STRATIFIED and sampler0 is not None
                    and sample_id is not None and not chain[:, 0].any()):
                # Every path here came straight through transparent surfaces (a fog
                # box's invisible faces, alpha): this is their first hit that bends,
                # stratified as at bounce 0 by each path's sample index and pixel.
                strat = sampler0.for_samples(sample_id if every else sample_id[dsel],
                                             np.asarray(pix if every else pix[dsel]) + pix_shift)
            g = glossy if every else glossy[dsel]
            # The shaded rows read in place (rows=dsel), or the batch itself: no copies of
            # their fields for the direct stage.
            counters.count("shaded", bounce, nd)
            sg = (np.zeros(nd, np.bool_) if shades is not None and bounce < depth_limit
                  and g.any() else None)
            # The glossy lobes' part of direct, for the light passes.
            g_part = np.zeros((nd, 3)) if lpass is not None and g.any() else None
            # Subsurface closures (engine/subsurfacewalk.py): wd keeps the diffuse share,
            # the BSSRDF's walks are shaded at their exits below (None: none here).
            walks = sss.entries(hit, None if every else dsel, wd) if sss is not None else None
            ctp = sampleclamp.split_throughput(tp, cscale) if clamping else None
            direct, caustic, indirect = shade_diffuse(
                ctx, hit, wd, rng, counters, strat, sample_id if every else sample_id[dsel],
                None if footprint is None else footprint[dsel], should_cancel, glossy=g,
                sel=sel if g.any() else None, buffers=buffers.direct,
                scattered=scattered if every or scattered is None else scattered[dsel],
                rows=None if every else dsel, bounce=bounce,
                extra=None if bounce == 0 else _chain_counts(chain if every else chain[dsel]),
                clamp_tp=(ctp if every else np.take(ctp, dsel, axis=0)) if clamping else None,
                shade_glossy=sg, glossy_out=g_part,
                used=(t_count if every else np.take(t_count, dsel))
                if bounce > 0 and t_count.any() else None)
            if sg is not None and sg.any():
                shade_rows = np.zeros(n, np.bool_)
                shade_rows[dsel[sg]] = True
            direct_raw = direct
            if clamping:
                # (A new array: direct may be the direct stage's buffers.)
                direct = sampleclamp.clamp(direct, ctp, dsel, sampleclamp.bounce_limits(
                    s, np.take(chain[:, 0], dsel)))
            if lpass is not None:
                # Direct light by lobe at a path's first bent bounce, the photon
                # estimates (light that bounced before) Diffuse Indirect; past it all
                # the path's Indirect. (Before the adds below: direct_raw may be the
                # direct stage's buffers, valid until its next use.)
                d_part, g_part = lightpasses.split_direct(
                    direct_raw, g_part, direct if clamping else None)
                lpass.shaded(pix, d_part, tp, dsel, lightpasses.DIFFUSE_DIRECT)
                if g_part is not None:
                    lpass.shaded(pix, g_part, tp, dsel, lightpasses.GLOSSY_DIRECT)
            _add_diffuse(acc, pix, tp, dsel, chain, bounce, limits[0], direct, caustic,
                         indirect)
            if lpass is not None and caustic is not None:
                lpass.shaded(pix, caustic + indirect, tp, dsel, lightpasses.DIFFUSE_INDIRECT)
            if walks is not None and len(walks[0]):
                if sss_rng is None:
                    # Their own stream (a child of rng's): paths without subsurface
                    # hits keep their numbers.
                    sss_rng = np.random.default_rng(rng.integers(1 << 62))
                _shade_subsurface(ctx, sss, walks, hit, dsel, acc, pix, tp, chain, medium,
                                  sample_id, footprint, bounce, sss_rng, counters,
                                  should_cancel, clamping, lpass, ctp,
                                  used=t_count if bounce > 0 and t_count.any() else None)
        if GLASS_LIGHT_SAMPLING:
            # Rough glass hits sample the lights behind their surface too (Cycles' light
            # sampling at every non-delta vertex; engine/glasslight.py). No rough glass:
            # no rows, no number drawn.
            if getattr(hit, "params", None) is not None:
                cand = np.nonzero(_transmitting(hit.params))[0]
            else:
                cand = (np.flatnonzero(np.take(glass_mat, hit.mat)) if glass_mat.any()
                        else _NO_ROWS)
            if over is not None and len(cand):
                cand = cand[~over[cand]]
            gl = (rough_transmission_rows(prm if hit.prm is None else hit.prm, cand)
                  if len(cand) else cand)
            if len(gl):
                if glass_rng is None:
                    # Their own stream (a child of bsdf_rng's, which it leaves as it was):
                    # every path that meets no rough glass keeps its numbers.
                    glass_rng = (bsdf_rng.spawn(1)[0] if bsdf_rng is not None
                                 else np.random.default_rng(rng.integers(1 << 62)))
                gsamples = light_sample_list(ctx, len(gl), glass_rng, modes=modes)
                glargs = (prm if hit.prm is None else hit.prm, sel, psum, modes)
                gcounts = None if bounce == 0 else _chain_counts(np.take(chain, gl, axis=0))
                Wg = None if shade_W is None else shade_W[gl]
                gused = (np.take(t_count, gl) if bounce > 0 and t_count.any() else None)
                if Wg is None or (Wg == 1.0).all():
                    Lt = transmitted_light(ctx, hit, gl, *glargs, gsamples, counters,
                                           counts=gcounts, used=gused)
                else:
                    # The served lamps' light apart, each by its weight (the same samples).
                    weighted = [li for li in sorted(shades.served) if (Wg[:, li] != 1.0).any()]
                    Lt = transmitted_light(ctx, hit, gl, *glargs,
                                           [e for e in gsamples if e[0] not in weighted],
                                           counters, counts=gcounts, used=gused)
                    for li in weighted:
                        Lt = Lt + Wg[:, li][:, None] * transmitted_light(
                            ctx, hit, gl, *glargs, [e for e in gsamples if e[0] == li],
                            counters, counts=gcounts, used=gused)
                if clamping:
                    Lt = sampleclamp.clamp(Lt, sampleclamp.split_throughput(tp, cscale), gl,
                                           sampleclamp.bounce_limits(
                                               s, np.take(chain[:, 0], gl)))
                acc.add("direct" if bounce == 0 else "specular", pix, Lt, tp, gl)
                if lpass is not None:
                    # The translucent lobe's share is Diffuse Direct (Cycles counts the
                    # Translucent BSDF among its diffuse closures), the rough glass
                    # refraction's Transmission Direct: split by the two lobes' albedos
                    # (exact where a surface has one of them).
                    translucent = lightpasses.translucent_share(ctx.table, hit, gl)
                    lpass.shaded(pix, Lt * translucent, tp, gl, lightpasses.DIFFUSE_DIRECT)
                    lpass.shaded(pix, Lt * (1.0 - translucent), tp, gl,
                                 lightpasses.TRANSMISSION_DIRECT)
        if bounce == depth_limit:
            return
        # Continue one specular lobe, chosen in proportion to its weight.
        # (Jittered by their own generator: the chunk's stream, and so every image
        # without a rough lobe, stays as it was.)
        # (Drawn only if a reflective lobe is sampled: bsdf_rng serves nothing else.)
        uv = (functools.partial(sampler.uv, ("bsdf",), rng=bsdf_rng)
              if sampler is not None and bounce == 0 and bsdf_rng is not None else None)
        # The lobe choice stratified too, its jitter from a child stream (bsdf_rng's left
        # as it was; spawned only where some hit has a choice to make).
        lobe_u = (functools.partial(_spawned_lobe_numbers, sampler, bsdf_rng)
                  if uv is not None and FIRST_HIT_LOBE_STRATIFIED else None)
        d_in, pdf_in = d, pdf_b
        tp_in, cls_in = tp, ray_cls
        cont = continue_specular(ctx, hit, tp, rng, ray_cls, choice=choice, want_pdf=True,
                                 uv=uv, split=None if may_split is None else may_split > 0,
                                 want_pass=True, lobe_u=lobe_u)
        keep, o, d, tp, ray_cls, pdf_b = cont[:6]
        pass_lobe = cont[-1]  # (the transparent passes among them)
        share = None
        if probe_world is not None and bounce == 0:
            # The world's light through the reflective lobes where it escapes: from the
            # continuation and WORLD_PROBES further reflections (world_probes), each its
            # share; the continuation alone where it meets a surface.
            prow = probe_rows(choice[2], choice[3], over)
            if len(prow):
                if probe_rng is None:
                    probe_rng = (bsdf_rng.spawn(1)[0] if bsdf_rng is not None
                                 else np.random.default_rng(rng.integers(1 << 62)))
                puv = None
                if sampler is not None and PROBES_STRATIFIED:
                    puv = (lambda j, smp=sampler, r=probe_rng: smp.uv(("probe", j), rng=r))
                er, Le = world_probes(ctx, hit, tp_in, choice, prow, probe_world, probe_rng,
                                      counters, puv, t_limit, t_count)
                acc.add("specular", pix, Le, None, er)
                if lpass is not None:  # (the world met one glossy bend on)
                    lpass.shaded(pix, Le, None, er, lightpasses.GLOSSY_DIRECT)
                share = np.ones(len(tp_in))
                qp = choice[1][prow]
                share[prow] = qp / (qp + WORLD_PROBES)
        if over is not None:
            # Past a limit: no bounce from here (the numbers drawn as for every path).
            go = ~over[keep]
            keep, o, d, tp, ray_cls, pdf_b, pass_lobe = (
                a[go] for a in (keep, o, d, tp, ray_cls, pdf_b, pass_lobe))
            if may_split is not None:
                cont = cont[:6] + (cont[6][go], cont[7][go])
            # But it passes a transparent share, unbent (Cycles' TERMINATE_AFTER_TRANSPARENT).
            extra = (passes_past_limit(ctx.table, hit, over_pass, d_in, tp_in, cls_in)
                     if over_pass is not None else (_NO_ROWS,))
            if len(extra[0]):
                keep, o, d, tp, ray_cls, pdf_b = (
                    np.concatenate((a, b)) for a, b in zip((keep, o, d, tp, ray_cls, pdf_b),
                                                           extra))
                pass_lobe = np.concatenate((pass_lobe, np.ones(len(extra[0]), bool)))
                if may_split is not None:
                    cont = cont[:6] + (np.concatenate((cont[6],
                                                       np.zeros(len(extra[0]), bool))),
                                       np.concatenate((cont[7], np.ones(len(extra[0])))))
        if fgblur is not None:
            # Each path's min_ray_pdf after this bounce: the continued direction's MIS pdf
            # (a pass, a mirror, smooth glass: inf, never the minimum).
            fgblur.continued(keep, pdf_b, choice[1], choice[3], w_diffuse, hit.ns, d)
        if medium is not None:
            # Refracted or passed into a medium, or out of it (engine/media.py): out of
            # an object's medium into the world volume's, if any.
            medium = media.after_continuation(ctx.geo, sigma, prim, d_in, keep, d, medium,
                                              outside=world_row)
        if may_split is not None:
            # A split path's two rays have one split less left.
            may_split = may_split[keep] - cont[6]
            if clamping and sampleclamp.SPLIT_SCALE:
                # Each half's clamp shrinks by the probability Cycles' glass sampling
                # would have taken it with (sampleclamp.split_throughput).
                if cscale is not None:
                    cscale = cscale[keep]
                if cont[6].any():
                    cscale = cont[7] if cscale is None else cscale * cont[7]
        # The bounce's kind (Cycles' path_state_next): a transparent pass (the pass lobe:
        # the ray goes on unbent) is none; else glossy or transmission by the continued
        # ray's class, an IOR 1 refraction's unbent ray too (Blender 5.0.1: a transmission
        # bounce, not a transparent one; docs/compatibility.md "### translimit49").
        chain = np.take(chain, keep, axis=0)
        bent = ~pass_lobe
        chain[:, 0] += bent
        if lpass is not None:
            lpass.take(keep)
            # (A translucent lobe's ray through the surface is a diffuse bounce to the
            # passes, as Cycles counts the Translucent BSDF among its diffuse closures.)
            lpass.bend(bent, lightpasses.pass_classes(
                ctx.table, np.take(hit.mat, keep), d, np.take(hit.ng, keep, axis=0),
                ray_cls))
        chain[:, 1] += bent & (ray_cls == GLOSSY)
        chain[:, 2] += bent & (ray_cls == TRANSMISSION)
        # The transparent passes (the pass lobe's continuations, a volume-only surface's
        # aside) count against Max Bounces > Transparent.
        t_count = np.take(t_count, keep)
        passed = pass_lobe
        if volume_only is not None:
            passed &= ~np.take(volume_only, np.take(hit.mat, keep))
        t_count += passed
        # (np.take(axis=0) gathers rows several times faster than fancy indexing.)
        org_ns_in = org_ns if kept is None else np.take(org_ns, kept, axis=0)
        org_p_in = org_p if kept is None else np.take(org_p, kept, axis=0)
        org_ns = np.take(hit.ns, keep, axis=0)
        org_p = np.take(hit.p, keep, axis=0)
        if link_prim is not None:
            link_prim = np.take(np.asarray(hit.prim, np.int64), keep)
        if org_prim is not None:
            org_prim = np.take(np.asarray(hit.prim, np.int64), keep)
            # (passages.step rewrites org_p in place after a flat passage)
            left_p = org_p if passages is None else org_p.copy()
        if GLASS_LIGHT_SAMPLING:
            # Rays refracted by rough glass or sent through a translucent lobe (a finite
            # pdf, below the geometric normal) left the far side: the lights' pdf there
            # (world, sphere lights, the light tree) is that of the samples
            # glasslight.transmitted_light takes, about the flipped normal.
            ngk = np.take(hit.ng, keep, axis=0)
            through = np.isfinite(pdf_b) & (
                d[:, 0] * ngk[:, 0] + d[:, 1] * ngk[:, 1] + d[:, 2] * ngk[:, 2] < 0.0)
            if through.any():
                org_ns[through] = -org_ns[through]
        if shades is not None:
            ngk = np.take(hit.ng, keep, axis=0)
            up = (d[:, 0] * ngk[:, 0] + d[:, 1] * ngk[:, 1] + d[:, 2] * ngk[:, 2]) > 0.0
            # Reflected rays of the hits whose glossy lobes took the shade samples.
            shade_from = (shade_rows[keep] & up & np.isfinite(pdf_b)
                          if shade_rows is not None else None)
            # Rays through a shade those paths met: its lamps' emission they meet is
            # weighted as the NEE there was.
            lamp_w = None
            if shade_W is not None:
                lamp_w = np.where((~up)[:, None], np.take(shade_W, keep, axis=0), 1.0)
        if passages is not None:
            passages.step(prim, d_in, hit.p, keep, d, pdf_in, org_ns_in, org_p_in, pdf_b,
                          org_ns, org_p)
        pix = pix[keep]
        world_share = None if share is None else np.take(share, keep)
        sample_id = sample_id[keep]
        travelled = travelled[keep]
        cam_dd = cam_dd[keep]
        if cam_dp0 is not None:
            cam_dp0 = cam_dp0[keep]
        if feat is not None:
            feat, ftp = feat[keep], ftp[keep]
        single, first = single[keep], first[keep]
        tmax = None
        counters.specular_rays += len(o)
