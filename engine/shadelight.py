"""Lamp light through a Translucent BSDF shade by next-event estimation (issue 14, shade32).

A lamp inside a shade (an open cylinder of Translucent BSDF) lights the room only through
the shade. Before, that light reached the room's diffuse surfaces only as caustic-kind
photons (effects: "light through translucent surfaces", the Caustic pass's k-NN
estimate): the right brightness but blotchy walls and floor, and small objects read dark
(docs/accuracy.md, lamp30 / caustic31). Here the shade is a secondary emitter whose
radiance is computed on the fly, as the sun through a single-plane pane
(engine/panelight.py) is a shadow ray through a transmissive surface.

Estimator (at a diffuse shading point x, normal N, for each light sample the direct
light takes of a served lamp): y is a point where the lamp's light lands on the shade,
chosen from the lamp's side: a direction from the lamp's centre (half cosine about the
direction to x, half uniform over the sphere; the sample's stratified numbers), y its
first hit, which must be a shade triangle, so y's area pdf is pdf_omega cos_in / r^2
(r, cos_in: the centre's distance and incidence at y). The closest hit from x towards y
must be the shade at y (nothing in between: the shade is opaque to shadow rays); from
y the lamp is sampled on the shade's far side by the direct light's own kernels
(directlight.direct_light with the normals flipped, as engine/glasslight.py samples
lights through rough glass): E_back(y), irradiance on the lamp's side. The Translucent
BSDF is Lambertian transmission, f_t = T / pi (T: its colour x its share), so the
shade's radiance towards x is L(y -> x) = T E_back(y) / pi and

    E(x) += T E_back(y) / pi * max(N . w, 0) |n_y . w| / (d^2 pdf_A(y)),   w = (y - x) / d.

For a point lamp E_back / pdf_A is nearly constant: what varies is the geometry towards
x. Choosing y from the lamp's side rather than x's (a cone towards the shade's
bounding sphere) matters for a tall open tube, whose radiance peaks at the lamp's
height: two tubes over a floor (tests/test_shade_light.py, 16 spp) read pixel std /
mean 0.44 sampled from x, 0.21 from the lamp, 0.15 with the stratified numbers.

Accounting (path classes and the estimator that counts each; x a camera-side diffuse
point, S the shade's translucent lobe, L a served lamp):
- L S x (lamp -> shade -> x, one crossing as the first scatter). Before: the caustic map
  at x (its photons kind CAUSTIC). After: this estimator alone; the photons of that path
  stay direct-kind (photonkernels: SHADE_TRANSLUCENT in pane_tri sets F_PANE, as a pane's
  sun photon), so neither the caustic map nor the glow shot holds them.
- L S z x (one diffuse bounce z after the shade). Before: the secondary map at x (kind
  CAUSTIC_DIFFUSE). After: the final gather from x reads the gather map at z, which now
  holds those photons as direct-kind (as every direct photon), and regathered points
  take this estimator in their direct light (integrator.direct_irradiance).
- x's rough reflective lobes (a wall's specular layer, sheen) towards the shade: their
  continuation meets the shade and samples the lamp through it (engine/glasslight.py),
  unchanged; only the diffuse lobe takes this estimator (as the pane's), so no path is
  counted twice. No MIS is needed: the diffuse lobe's only other strategy through the
  shade is the final gather, whose rays continue through the translucent lobe
  (continue_specular) but never add a lamp's emission (lamps are not in the BVH; a gather
  counts mesh emission only on its own first hit at levels > 0).
- Paths crossing the shade twice, or a transparent pass after it, another bounce first,
  or from a lamp not served (a mesh light, the world, a sun): caustic photons, as before.
- Known gap: a Transparent BSDF surface between the lamp and the shade. Its photons
  keep their kind through the pass and stay direct at the shade, but the lamp-side ray
  that picks y stops at that surface, so this light is counted by neither (not
  measured; no test scene has one).

Which shades: materials that are all Translucent BSDF (share 1, opaque, no texture,
normal map or emission; a Mix with another surface keeps its photons), in a scene
without shared instances and with few enough lights that each is sampled on its own (no
light tree), rendered with shadow rays (not method 'local'). Served lamps: point and
spot lights whose shadow rays are sampled (y is chosen from the lamp's centre: a lamp
with a radius is sampled over its size from y, but a shade point its centre cannot see,
behind an occluder right at the lamp, is missed; an area light is not served: its light
through a shade stays caustic). Rough glass shades are not served either (their light
stays caustic).
"""
from __future__ import annotations

import math

import numpy as np

from . import photonkernels as pk
from .parallel import once_on
from .sampling import orthonormal_basis

# Off: every shade stays caustic, as before (A/B measurements: bench/bench_lamp_room.py).
ENABLED = True
# Light kinds served (their photons through a shade stay direct).
SERVED_KINDS = ("POINT", "SPOT")
# The share of shade samples drawn about the direction to the shading point
# (_lamp_directions); the rest uniform over the sphere.
LAMP_COSINE_SHARE = 0.5

_NO_ROWS = np.zeros(0, np.int64)
_NO_ROWS3 = np.zeros((0, 3))


class Shades:
    """The scene's next-event shades: `tl` (M,3) each material's translucent
    transmittance T (0: not a shade material); `served` the light indices (into
    ctx.lights) sampled through them (a frozenset), `lights` those Light objects; `names`
    the shade objects' names; `code` (T,) int64 the photon kernel's pane_tri codes (-1, or
    photonkernels.SHADE_TRANSLUCENT on a shade triangle)."""

    def __init__(self, tl, served, lights, names, code):
        self.tl, self.served, self.lights = tl, frozenset(served), lights
        self.names, self.code = names, code

    def photon_tri(self, light, pane_tri=None) -> np.ndarray | None:
        """pane_tri for the photons of `light` (photonkernels.scatter): this scene's shade
        triangle codes (SHADE_TRANSLUCENT) where `light` is served, else pane_tri (the
        panes' table or None) unchanged. Panes serve suns and the world only
        (engine/panelight.py) and shades point and spot lamps, so no light needs both."""
        inner = getattr(light, "light", light)  # (a RegionEmitter wraps the light)
        if not any(inner is s for s in self.lights):
            return pane_tri
        assert pane_tri is None or len(pane_tri) == 0, "a light served by panes and shades"
        return self.code


def shade_materials(table) -> tuple[np.ndarray, np.ndarray]:
    """((M,) bool, (M,3) float64): the materials that are a Translucent BSDF alone (share
    1, opaque, untextured, no normal map or emission, closure weight 1) and their
    transmittance T (the translucent colour, or the base colour without one; 0
    elsewhere)."""
    from .closures import principled as pr
    q = np.asarray(table.closure_params, np.float64)
    M = len(q)
    if M == 0:
        return np.zeros(0, bool), np.zeros((0, 3))

    def untextured(nodes):
        return np.array([x is None for x in (nodes or [None] * M)], bool)

    ok = ((q[:, pr.M_TL] >= 1.0) & (np.asarray(table.alpha, np.float64) >= 1.0)
          & (q[:, pr.M_ADD] == 0.0)
          & (np.asarray(table.emission, np.float64) == 0.0).all(axis=1)
          & untextured(table.textures) & untextured(table.normal_maps)
          & untextured(table.alpha_textures) & untextured(table.scalar_textures)
          & untextured(getattr(table, "emission_textures", None)))
    col = np.where(q[:, pr.M_HAS_TLCOL:pr.M_HAS_TLCOL + 1] != 0.0,
                   q[:, pr.M_TLCOL:pr.M_TLCOL + 3], np.asarray(table.base_color, np.float64))
    tl = np.where(ok[:, None], np.maximum(col, 0.0) * q[:, pr.M_TL:pr.M_TL + 1], 0.0)
    return ok & (tl.max(axis=1) > 0.0), tl


def find_shades(geo, table, lights, settings=None):
    """Shades or None (the module docstring's conditions): the triangles of Translucent
    BSDF materials, with the point and spot lights they serve (SERVED_KINDS)."""
    if not ENABLED or geo.count == 0 or getattr(geo, "shared", None) is not None:
        return None
    if settings is not None and getattr(settings, "method", None) == "local":
        return None  # (no shadow rays: its direct light is unoccluded)
    from .geometry import SHADOW
    from .lights.selection import SAMPLE_ALL_UP_TO
    if len(lights) > SAMPLE_ALL_UP_TO:
        return None  # the light tree picks one light per shadow ray
    served = [i for i, li in enumerate(lights) if getattr(li, "kind", None) in SERVED_KINDS
              and int(li.ray_kinds) & SHADOW and li.shadow_sampled]
    if not served:
        return None
    ok, tl = shade_materials(table)
    if not ok.any():
        return None
    mat = np.asarray(geo.material)
    tri = np.flatnonzero(ok[mat]).astype(np.int64)
    area = 0.5 * np.linalg.norm(np.cross(geo.e1[tri], geo.e2[tri]), axis=1)
    tri = tri[area > 0.0]
    if not len(tri):
        return None
    code = np.full(geo.count, -1, np.int64)
    code[tri] = pk.SHADE_TRANSLUCENT
    names = [geo.object_names[o] for o in np.unique(np.asarray(geo.object_id)[tri])]
    return Shades(tl, served, [lights[i] for i in served], names, np.ascontiguousarray(code))


def shades_for(ctx):
    """The context's Shades (or None), found once and kept on it."""
    return once_on(ctx, "_shades",
                   lambda: find_shades(ctx.geo, ctx.table, ctx.lights, ctx.settings))


def _lamp_directions(a, r):
    """(N,3) unit directions from a lamp's centre and their solid-angle pdf (N,), from
    numbers r = (r0, r1) (each (N,)): the one-sample mixture, by r0 < LAMP_COSINE_SHARE,
    of the cosine lobe about the unit axes a (N,3) (towards the shading points) and the
    uniform sphere; pdf = share cos+ / pi + (1 - share) / (4 pi) (the uniform half keeps
    every direction's pdf >= 1 / (8 pi): the shade's faces the cosine lobe misses, the
    tube's ends above a floor point, stay sampled)."""
    # One number picks the strategy and, rescaled within its share, the polar angle:
    # the pixel's stratified numbers stay stratified over both.
    share = LAMP_COSINE_SHARE
    cosine = r[0] < share
    v = np.where(cosine, r[0] / share, (r[0] - share) / (1.0 - share))
    v = np.clip(v, 0.0, 1.0)
    ct = np.where(cosine, np.sqrt(v), 1.0 - 2.0 * v)
    st = np.sqrt(np.maximum(0.0, 1.0 - ct * ct))
    phi = 2.0 * math.pi * r[1]
    bu, bv = orthonormal_basis(a)
    w = (st * np.cos(phi))[:, None] * bu + (st * np.sin(phi))[:, None] * bv + ct[:, None] * a
    cos_a = np.maximum(np.einsum("ij,ij->i", w, a), 0.0)
    return w, LAMP_COSINE_SHARE * cos_a / math.pi + (1.0 - LAMP_COSINE_SHARE) * 0.25 / math.pi


def shade_irradiance(ctx, shades, p, ns, ng, offset, samples, rng):
    """(N,3) irradiance at points p (N,3) (shading normals ns, geometric normals ng on the
    viewer's side, origin offsets offset (N,)) from the served lights' samples among
    `samples` (integrator.light_sample_list entries: each one's u1, u2 choose the point
    on the lamp seen from the shade) through the shades, and the shadow rays traced. rng
    (numpy Generator, the caller's seeded stream): the point on the lamp seen from y, 2
    numbers per point and sample.

    Each sample picks y where the lamp's light lands: a direction from the lamp's centre
    (_lamp_directions, about the direction to the shading point), y its first hit, which
    must be a shade triangle; the area pdf of y is pdf_omega cos_in / r^2 (cos_in at y's
    geometric normal, r the centre's distance), so a point lamp's E_in(y) / pdf is
    nearly constant and only the geometry towards x varies. Then the closest hit from x
    towards y must be y's shade at y's distance (shadow ray), the lamp is sampled from
    y's far side (E_back, directlight.direct_light with the normals flipped), and
    E += T E_back / pi max(N . w, 0) |n_y . w| / (d^2 pdf_A). A lamp with a radius is
    sampled over its whole size at y, but y is chosen from its centre: a shade point the
    centre cannot see (an occluder right at the lamp) is missed."""
    from .bsdf import surface_hit
    from .directlight import direct_light
    from .geometry import SHADOW
    from .lights.packing import pack_lights
    N = len(p)
    E = np.zeros((N, 3))
    if N == 0 or shades is None:
        return E, 0
    packed = ctx.packed_lights or pack_lights(ctx.lights)
    geo, accel = ctx.geo, ctx.accel
    shadow = getattr(ctx, "shadow", None)
    scale = max(float(geo.extent), 1e-9)
    rays = 0
    c = np.ascontiguousarray
    for li, traced, count, u1, u2, sel in samples:
        if li < 0 or li not in shades.served:
            continue
        centre = np.asarray(ctx.lights[li].pos, np.float64).reshape(3)
        # The direction from the lamp takes the sample's stratified numbers (u1, u2);
        # the point on the lamp seen from y, fresh ones.
        lamp_u = rng.random((2, N))
        to_x = p - centre
        dx = np.sqrt(np.einsum("ij,ij->i", to_x, to_x))
        idx = np.flatnonzero(dx > 1e-9 * scale)
        if not len(idx):
            continue
        wl, pdf_w = _lamp_directions(to_x[idx] / dx[idx, None], (u1[idx], u2[idx]))
        # Where the lamp's light lands: its first hit, a shade triangle.
        o_l = c(np.broadcast_to(centre, (len(idx), 3)))
        t_l, prim, hu, hv = accel.intersect(o_l, c(wl), None, cls=SHADOW)
        rays += len(idx)
        good = (prim >= 0) & (np.take(shades.code, np.maximum(prim, 0)) == pk.SHADE_TRANSLUCENT)
        good &= np.isfinite(t_l) & (t_l > 0.0)
        idx, wl, pdf_w, t_l, prim, hu, hv = (a_[good] for a_ in
                                             (idx, wl, pdf_w, t_l, prim, hu, hv))
        if not len(idx):
            continue
        y = centre + t_l[:, None] * wl
        o = p[idx] + offset[idx, None] * ng[idx]
        d = y - o
        dist = np.sqrt(np.einsum("ij,ij->i", d, d))
        w = d / np.maximum(dist, 1e-300)[:, None]
        cr = np.einsum("ij,ij->i", w, ns[idx])
        cg = np.einsum("ij,ij->i", w, ng[idx])
        keep = (cr > 0.0) & (cg > 0.0) & (dist > 1e-6 * scale)
        idx, wl, pdf_w, t_l, prim, hu, hv, o, w, dist, cr = (
            a_[keep] for a_ in (idx, wl, pdf_w, t_l, prim, hu, hv, o, w, dist, cr))
        if not len(idx):
            continue
        # From x, the first surface towards y: y's shade, at y's distance.
        t_hit, prim_x, _, _ = accel.intersect(c(o), c(w), dist * (1.0 + 1e-3) + 1e-5 * scale,
                                              cls=SHADOW)
        rays += len(idx)
        seen = (prim_x >= 0) & (np.take(shades.code, np.maximum(prim_x, 0))
                                == pk.SHADE_TRANSLUCENT)
        seen &= np.abs(t_hit - dist) <= 1e-3 * dist + 1e-5 * scale
        idx, wl, pdf_w, t_l, prim, hu, hv, w, dist, cr = (
            a_[seen] for a_ in (idx, wl, pdf_w, t_l, prim, hu, hv, w, dist, cr))
        if not len(idx):
            continue
        # y's surface as the ray from x meets it: normals turned towards x.
        Y = surface_hit(geo, ctx.table, prim, hu, hv, w)
        yng = np.asarray(Y.ng, np.float64)
        cos_in = np.abs(np.einsum("ij,ij->i", wl, yng))
        cos_y = np.abs(np.einsum("ij,ij->i", w, yng))
        # The lamp on the shade's far side: normals flipped (engine/glasslight.py).
        yns = c(-np.asarray(Y.ns, np.float64))
        arrays = (c(Y.p, np.float64), yns, _NO_ROWS3, c(-yng), c(Y.offset, np.float64),
                  _NO_ROWS, _NO_ROWS, _NO_ROWS3, yns)
        entry = [(li, traced, count, c(lamp_u[0, idx]), c(lamp_u[1, idx]),
                  None if sel is None else c(sel[idx], np.float64))]
        Eb, nr = direct_light(packed, arrays, entry, accel, SHADOW, len(idx), shadow=shadow)
        rays += nr
        pdf_a = pdf_w * cos_in / (t_l * t_l)
        T = shades.tl[np.asarray(Y.mat)]
        g = cr * cos_y / (math.pi * dist * dist * np.maximum(pdf_a, 1e-300))
        E[idx] += T * Eb * g[:, None]
    return E, rays
