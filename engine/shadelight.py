"""Lamp light through a Translucent BSDF or rough glass shade by next-event estimation
(issue 14, shade32; rough glass: roughshade33).

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

A single-surface rough glass shade (a Glass BSDF, or Principled at Transmission 1,
roughness GLASS_ROUGH_MIN .. 1: an open cylinder or a cone without thickness) is the
same estimator with the glass's refraction for the Lambertian transmission: y's radiance
towards x is the lamp's light refracted by the rough glass lobe,

    L(y -> x) = f_t(w_lamp, w_x) L_lamp |n_y . w_lamp| / pdf_lamp

over the lamp samples from y's far side, by the camera side's own evaluation
(engine/glasslight.py: directlight.direct_light with `transmission`,
principled.accumulate_transmission at full weight), its lobes set up at y for the view
towards x (bsdf.closures): the Multiscatter GGX compensation is taken on x's side, as
Cycles' path from x takes it and as the photons' glass_adjoint documents; the
interface's eta and which side the lamp is on follow the winding normals, as the camera
side's. The lobe is peaky (roughness 0.3: alpha 0.09), so besides the lamp-side choice
of y a share GLASS_PEAK_SHARE of the samples is drawn in a lobe about the lamp direction
the glass refracts straight towards x (_refracted_axes: two rays from the lamp find it by
a fixed-point step, starting towards x or, where that ray leaves through an opening,
towards the nearest glass triangle; GGX's distribution for a radius-0 lamp, cos^n for a
lamp with a radius, which also takes GLASS_LAMP_SAMPLES points on the lamp per y, in
jittered strata), the pdf being the mixture's; only lamps near a glass shade
(Shades.near_glass) take the peak. Per-sample std / mean at roughness 0.3, three points by a tube:
11-20 from the lamp side alone, 1.7-4.6 with the mixture; at 0.5, 5-8.5 -> 0.9-1.3; by
the living room's shade 0.6-1.5 (Translucent: 1.1-1.6) (docs/accuracy.md
"## roughshade33", bench/bench_glass_shade.py). Below roughness 0.3 (GLASS_ROUGH_MIN) the
estimator's pixel noise exceeds the caustic photons' (at 0.2: pixel std / mean 1.6 at 64
spp, the photons' 1.3): that glass stays caustic.

For a point lamp E_back / pdf_A is nearly constant: what varies is the geometry towards
x. Choosing y from the lamp's side rather than x's (a cone towards the shade's
bounding sphere) matters for a tall open tube, whose radiance peaks at the lamp's
height: two tubes over a floor (tests/test_shade_light.py, 16 spp) read pixel std /
mean 0.44 sampled from x, 0.21 from the lamp, 0.15 with the stratified numbers.

Accounting (path classes and the estimator that counts each; x a camera-side diffuse
point, S the shade's translucent lobe, L a served lamp):
- L S x (lamp -> shade -> x, one crossing as the first scatter: the translucent lobe, or
  a rough glass shade's refraction). Before: the caustic map at x (its photons kind
  CAUSTIC). After: this estimator alone; the photons of that path stay direct-kind
  (photonkernels: SHADE_TRANSLUCENT / SHADE_GLASS in pane_tri sets F_PANE, as a pane's
  sun photon), so neither the caustic map nor the glow shot holds them.
- L R x, R a rough glass shade's reflection (the lamp's light off the shade's inside,
  out through its openings; or a second crossing after it): caustic photons, as before
  (their scatter is not the refraction, so SHADE_GLASS leaves their kind; no shadow ray
  carries reflected light).
- L S z x (one diffuse bounce z after the shade). Before: the secondary map at x (kind
  CAUSTIC_DIFFUSE). After: the final gather from x reads the gather map at z, which now
  holds those photons as direct-kind (as every direct photon), and regathered points
  take this estimator in their direct light (integrator.direct_irradiance).
- L S x', x' a camera point's rough reflective lobes (Principled specular layer, metal,
  coat, sheen; Glossy BSDF: whatever principled.eval_reflection evaluates for the direct
  light) seen from the camera (glossshade34). Two strategies find it, combined by
  multiple importance sampling with the power heuristic (Veach 1997, ch. 9):
  (a) light side, shade_light(glossy=): the same shade samples y as the diffuse lobe's,
  Lg += L(y -> x) f(wo, w) cos / pdf_w x w_a, pdf_w = pdf_A(y) d^2 / |n_y . w| (y's
  area pdf converted to solid angle at x), w_a = (n pdf_w)^2 / ((n pdf_w)^2 + pdf_b^2),
  n the lamp's light samples, pdf_b principled.bsdf_pdf (the continuation's mixture over
  its lobes with its lobe-choice probabilities sel, as directlight.accumulate_bsdf's MIS);
  (b) BSDF side: the continuation reflected at x meets the shade at y (its first hit),
  where the camera path takes the lamp through the shade by NEE
  (engine/glasslight.py, itself MIS'd against y's refraction) and, next bounce, the
  lamp's sphere met by that refraction: both are the path's estimate of L(y -> x) and
  both take w_b = pdf_b^2 / (pdf_b^2 + (n pdf_w)^2) (shade_bsdf_weights; integrator's
  shade_W in the glass stage, lamp_w at the lamp's hit), pdf_w computed for that y as
  (a) would have drawn it (_strategy, direction_pdf: the same mixture, the same lamp-side
  first-hit condition; 0 where (a) cannot draw y: then w_b = 1). w_a + w_b = 1 for every
  y both can reach (tests/test_glossy_shade_light.py: each side alone and the MIS sum
  equal a grid integral). Only the served lamps' light through the shade is weighted:
  other lights y passes on, y's reflection and what follows keep their full weight.
  Mirror-like lobes (no density: pdf_b inf) keep w_b = 1 and take no light-side sample;
  a continuation through x (refraction) is not reflected, w_b = 1. The light side takes
  the same bounce limits as the continuation's hit at y (a glossy bounce: x's counts +
  (1, 0, 1, 0)); integrator.shade_diffuse's shade_glossy marks the rows that took it,
  whose reflected rays alone are weighted (at the camera's depth limit no continuation
  follows and the light side keeps w_a, as accumulate_bsdf's MIS lights do there). Not
  handled: a continuation that crosses a flat glass passage before the shade (its x is
  moved, CameraPassages) takes x's weight as if it had not (no test scene has one). Before:
  (b) alone at full weight, the glass's peaky lobe met rarely (newuser33's sparkles).
  The diffuse lobe's own estimate stays as it was (no MIS: its only other strategy
  through the shade is the final gather, which adds no lamp's emission).
- Paths crossing the shade twice, or a transparent pass after it, another bounce first,
  or from a lamp not served (a mesh light, the world, a sun): caustic photons, as before.
- Known gap: a Transparent BSDF surface between the lamp and the shade. Its photons
  keep their kind through the pass and stay direct at the shade, but the lamp-side ray
  that picks y stops at that surface, so this light is counted by neither (not
  measured; no test scene has one).

Which shades: materials that are all Translucent BSDF (share 1, opaque, no texture,
normal map or emission; a Mix with another surface keeps its photons) or all rough glass
(glass_shade_materials: roughness GLASS_ROUGH_MIN .. 1; smoother glass stays caustic, the
caustic map focuses it better), in a scene
without shared instances and with few enough lights that each is sampled on its own (no
light tree), rendered with shadow rays (not method 'local'). Served lamps: point and
spot lights whose shadow rays are sampled (y is chosen from the lamp's centre: a lamp
with a radius is sampled over its size from y, but a shade point its centre cannot see,
behind an occluder right at the lamp, is missed; an area light is not served: its light
through a shade stays caustic). A rough glass shade with thickness (two surfaces):
the light crossing both is a second crossing, caustic photons as before, and the
estimator finds only what the inner face sends out through the openings (not measured:
shades of one surface are the common case).
"""
from __future__ import annotations

import math

import numpy as np

from . import photonkernels as pk
from . import raymaterials
from .parallel import once_on
from .sampling import orthonormal_basis

# Off: every shade stays caustic, as before (A/B measurements: bench/bench_lamp_room.py).
ENABLED = True
# The camera points' rough reflective lobes (specular, metal, coat, sheen, Glossy BSDF)
# take the shade samples too, by MIS against the continuation that meets the shade
# (glossshade34); False: the diffuse lobe alone, the glossy lobes' light through the
# shade from reflected rays alone, as before (A/B: docs/accuracy.md "## glossshade34").
SERVE_GLOSSY = True
# Light kinds served (their photons through a shade stay direct).
SERVED_KINDS = ("POINT", "SPOT")
# The share of shade samples drawn about the direction to the shading point
# (_lamp_directions); the rest uniform over the sphere.
LAMP_COSINE_SHARE = 0.5

# Rough glass shades (single surface, Glass BSDF or Principled Transmission 1): served
# from this roughness up (below it the lobe is too peaky for y chosen from the lamp;
# the caustic map keeps that light: docs/accuracy.md "## roughshade33").
GLASS_ROUGH_MIN = 0.3
# The share of a glass shade's samples drawn in the lobe about the lamp's direction
# that the glass refracts towards the shading point (_refracted_axes); GLASS_PEAK_WIDTH:
# that lobe's angular spread over the glass's alpha (cos^n lobe, n = 2 / (k alpha)^2).
GLASS_PEAK_SHARE = 0.9
GLASS_PEAK_WIDTH = 1.0
# The peaked lobe's shape: GGX's distribution about the axis for a lamp of radius 0 (its
# heavier tails follow the glass's own), a cos^n lobe for a lamp with a radius (whose
# size smears the peak); None: by the lamp, or "ggx" / "cos" for all. Their spreads:
# GLASS_PEAK_WIDTH x GLASS_PEAK_BASE[lobe] x alpha (bench/bench_glass_shade.py).
GLASS_PEAK_LOBE = None
GLASS_PEAK_BASE = {"ggx": 0.5, "cos": 1.0}
# Points on a lamp with a radius sampled from each y on a glass shade (their shadow rays
# and f_t evaluations; the rays choosing y are shared): the point on the lamp moves the
# glass's peak (one per y left std / mean 1.6-2.5 by a radius-0.05 m lamp, 8: 0.8-1.0).
# newuser33's corner (glossshade34): 4 per y -7 % CPU, +67 % seed-pair noise; 8 stays;
# stratified (GLASS_LAMP_STRATIFIED) its seed-pair noise 0.0094 -> 0.0074 at the same CPU.
GLASS_LAMP_SAMPLES = 8
# Which lamps take the glass peak (Shades.near_glass): a centre inside a glass shade
# object's bounding box grown by this share of its largest side. The peak finds the
# direction a lamp's light refracts towards x through its own shade; a lamp across the
# room from a glass shade sampled its peak for every point (_refracted_axes' rays) for
# the little light it sends through that glass, which the lamp-side choice still finds.
GLASS_NEAR = 0.5
# The GLASS_LAMP_SAMPLES points on the lamp seen from y in jittered strata of its
# sampling square (_strata: nx x ny cells; a count with no such grid: 1 x n).
GLASS_LAMP_STRATIFIED = True
# _refracted_axes' fixed-point steps after its first ray (0: the peak read at the point
# where the lamp's ray towards x meets the shade).
GLASS_PEAK_STEPS = 1
# Where the lamp's ray towards x misses the shade (x above or below it: the light leaves
# the shade's wall towards x, the ray passes through an opening), the steps start from
# the glass triangle whose centroid is closest in angle to that ray, among at most this
# many (evenly taken) triangles.
GLASS_START_POINTS = 1024

_NO_ROWS = np.zeros(0, np.int64)
_NO_ROWS3 = np.zeros((0, 3))


class Shades:
    """The scene's next-event shades: `tl` (M,3) each material's translucent
    transmittance T (0: not a translucent shade material); `served` the light indices
    (into ctx.lights) sampled through them (a frozenset), `lights` those Light objects;
    `names` the shade objects' names (`glass_names` those of rough glass); `code` (T,)
    int64 the photon kernel's pane_tri codes (-1, or photonkernels.SHADE_TRANSLUCENT /
    SHADE_GLASS on a shade triangle)."""

    def __init__(self, tl, served, lights, names, code, glass_names=(), glass_centroids=None,
                 glass_boxes=None):
        self.tl, self.served, self.lights = tl, frozenset(served), lights
        self.names, self.code = names, code
        self.glass_names = list(glass_names)
        self.has_glass = bool(np.any(code == pk.SHADE_GLASS))
        # (K,3) centroids of (at most GLASS_START_POINTS of) the glass shade triangles:
        # _refracted_axes' start where the lamp's ray towards x misses the shade.
        self.glass_centroids = (np.zeros((0, 3)) if glass_centroids is None
                                else glass_centroids)
        # (G,2,3) each glass shade object's bounding box grown by GLASS_NEAR x its largest
        # side: the lamps whose centre lies in one take the glass peak (near_glass).
        self.glass_boxes = np.zeros((0, 2, 3)) if glass_boxes is None else glass_boxes

    def near_glass(self, centre) -> bool:
        """Whether a lamp at centre (3,) is near a rough glass shade (inside a grown box of
        glass_boxes): only those lamps' samples take the glass peak (_strategy); a lamp
        elsewhere samples the shades from its side alone, no _refracted_axes rays."""
        b = self.glass_boxes
        return bool(len(b) and np.any(np.all((b[:, 0] <= centre) & (centre <= b[:, 1]),
                                              axis=1)))

    def photon_tri(self, light, pane_tri=None) -> np.ndarray | None:
        """pane_tri for the photons of `light` (photonkernels.scatter): this scene's shade
        triangle codes (SHADE_TRANSLUCENT, SHADE_GLASS) where `light` is served, else
        pane_tri (the panes' table or None) unchanged. Panes serve suns and the world only
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


def glass_shade_materials(table) -> np.ndarray:
    """(M,) bool: the materials that are rough glass alone: a Glass BSDF, a Refraction
    BSDF or a Principled BSDF at Transmission 1 (no metallic, coat, sheen or translucent
    share, isotropic), roughness GLASS_ROUGH_MIN .. 1, opaque, untextured, no normal map
    or emission, closure weight 1. On a single surface (an open cylinder, a cone without
    thickness) the interface's sides follow its normals, as the camera side's
    (engine/glasslight.py)."""
    from .closures import principled as pr
    q = np.asarray(table.closure_params, np.float64)
    M = len(q)
    if M == 0:
        return np.zeros(0, bool)

    def untextured(nodes):
        return np.array([x is None for x in (nodes or [None] * M)], bool)

    node = q[:, pr.M_NODE]
    glass_node = (node == pr.NODE_GLASS) | (node == pr.NODE_REFRACTION)
    principled = ((node == pr.NODE_PRINCIPLED) & (q[:, pr.M_METALLIC] == 0.0)
                  & (q[:, pr.M_COAT_W] == 0.0) & (q[:, pr.M_SHEEN_W] == 0.0))
    return ((glass_node | principled) & (q[:, pr.M_TRANS] >= 1.0) & (q[:, pr.M_TL] == 0.0)
            & (q[:, pr.M_ANISO] == 0.0)
            & (q[:, pr.M_ROUGH] >= GLASS_ROUGH_MIN) & (q[:, pr.M_ROUGH] <= 1.0)
            & (np.asarray(table.alpha, np.float64) >= 1.0) & (q[:, pr.M_ADD] == 0.0)
            & (np.asarray(table.emission, np.float64) == 0.0).all(axis=1)
            & (np.asarray(table.base_color, np.float64).max(axis=1) > 0.0)
            & untextured(table.textures) & untextured(table.normal_maps)
            & untextured(table.alpha_textures) & untextured(table.scalar_textures)
            & untextured(getattr(table, "emission_textures", None)))


def find_shades(geo, table, lights, settings=None):
    """Shades or None (the module docstring's conditions): the triangles of Translucent
    BSDF and single-surface rough glass shade materials, with the point and spot lights
    they serve (SERVED_KINDS)."""
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
    glass = glass_shade_materials(table) & ~ok
    # A shade that shadow rays see as another material (Light Path: Is Shadow Ray) lets
    # them through as that material says (engine/raymaterials.py): not a shade here.
    other = raymaterials.differs(table, SHADOW)
    ok, glass = ok & ~other, glass & ~other
    if not (ok.any() or glass.any()):
        return None
    mat = np.asarray(geo.material)
    code = np.full(geo.count, -1, np.int64)
    obj = np.asarray(geo.object_id)
    names, glass_names = [], []
    for kind, sel, out in ((pk.SHADE_TRANSLUCENT, ok, names),
                           (pk.SHADE_GLASS, glass, glass_names)):
        tri = np.flatnonzero(sel[mat]).astype(np.int64)
        area = 0.5 * np.linalg.norm(np.cross(geo.e1[tri], geo.e2[tri]), axis=1)
        tri = tri[area > 0.0]
        code[tri] = kind
        out += [geo.object_names[o] for o in np.unique(obj[tri])]
    if not (code < -1).any():
        return None
    gt = np.flatnonzero(code == pk.SHADE_GLASS)
    if len(gt) > GLASS_START_POINTS:
        gt = gt[np.linspace(0, len(gt) - 1, GLASS_START_POINTS).astype(np.int64)]
    centroids = np.asarray(geo.v0, np.float64)[gt] + (np.asarray(geo.e1, np.float64)[gt]
                                                      + np.asarray(geo.e2, np.float64)[gt]) / 3.0
    boxes = []
    all_glass = np.flatnonzero(code == pk.SHADE_GLASS)
    for ob in np.unique(obj[all_glass]):
        t_ = all_glass[obj[all_glass] == ob]
        pts = np.concatenate([np.asarray(geo.v0, np.float64)[t_],
                              np.asarray(geo.v0, np.float64)[t_] + np.asarray(geo.e1)[t_],
                              np.asarray(geo.v0, np.float64)[t_] + np.asarray(geo.e2)[t_]])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        grow = GLASS_NEAR * float((hi - lo).max())
        boxes.append((lo - grow, hi + grow))
    return Shades(tl, served, [lights[i] for i in served], names + glass_names,
                  np.ascontiguousarray(code), glass_names, np.ascontiguousarray(centroids),
                  np.asarray(boxes, np.float64).reshape(-1, 2, 3))


def shades_for(ctx):
    """The context's Shades (or None), found once and kept on it."""
    return once_on(ctx, "_shades",
                   lambda: find_shades(ctx.geo, ctx.table, ctx.lights, ctx.settings))


def next_event_tri(ctx, light) -> np.ndarray | None:
    """The photon kernel's pane_tri for the photons of `light` (photonkernels._scatter's
    F_PANE test): per triangle row, the next-event pane index (>= 0) where `light` is a
    sun or the world that the panes serve (engine/panelight.py), SHADE_TRANSLUCENT /
    SHADE_GLASS on the shade triangles where it is a lamp the shades serve, -1
    elsewhere; None or empty: no surface whose shadow rays carry this light. The light
    refracted through (or, at a translucent shade, transmitted by) such a triangle as the
    first scatter of its path to a diffuse point is that point's direct light, so the
    caustic map holds no photon of it and the Filter Glossy split's chains
    (glossysplit.GatherChains) sample none of it there."""
    from .panelight import panes_for
    panes = panes_for(ctx)
    tri = panes.photon_tri(light) if panes is not None else None
    shades = shades_for(ctx)
    if shades is not None:
        tri = shades.photon_tri(light, tri)
    return tri


def carried_at(tri, prim) -> np.ndarray:
    """(K,) bool: whether the triangle rows prim (K,) int64 carry the light of
    next_event_tri's table tri by next-event shadow rays through them: a pane, a rough
    glass shade (its refraction) or a translucent shade (the photon kernel's F_PANE
    codes)."""
    if tri is None or not len(tri):
        return np.zeros(len(prim), bool)
    code = np.take(tri, np.asarray(prim, np.int64))
    return (code >= 0) | (code == pk.SHADE_GLASS) | (code == pk.SHADE_TRANSLUCENT)


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


def _refracted_axes(ctx, shades, centre, a, x):
    """((N,3) lamp directions, (N,) bool valid, (N,) int64 the glass's material, rays
    traced): for each shading point x (N,3) seen from the lamp's centre along a (N,3),
    the direction from the lamp whose light the rough glass shade refracts straight
    towards x, by _peak_steps from a; where the lamp's ray along a misses the glass (x
    above or below the shade), from the direction to the glass triangle centroid
    closest in angle to a (Shades.glass_centroids). It only centres the mixture's peaked
    lobe (_shade_directions), whose estimate stays unbiased."""
    out, valid, mat, rays = _peak_steps(ctx, shades, centre, a, x)
    miss = np.flatnonzero(~valid)
    cen = shades.glass_centroids
    if len(miss) and len(cen):
        to_c = cen - centre
        to_c /= np.maximum(np.linalg.norm(to_c, axis=1), 1e-300)[:, None]
        # (in chunks: the (rows, centroids) cosines stay a few MB)
        step = max(1, (1 << 20) // len(cen))
        start = np.concatenate([to_c[np.argmax(a[miss[i:i + step]] @ to_c.T, axis=1)]
                                for i in range(0, len(miss), step)])
        o2, v2, m2, r2 = _peak_steps(ctx, shades, centre, start, x[miss])
        out[miss], valid[miss], mat[miss] = o2, v2, m2
        rays += r2
    return out, valid, mat, rays


def _peak_steps(ctx, shades, centre, a, x):
    """_refracted_axes' fixed-point steps from the directions a (N,3): the lamp's ray
    along the current axis meets the shade at y0 (valid where that is a SHADE_GLASS
    triangle), the ray from x to y0 refracts through y0's geometric normal (the
    interface's sides by the winding, eta 1 / ior entering the front, as
    principled.glass_terms) into t, and the lamp's light that leaves y0 towards x
    arrives along -t (reversibility): the next axis. 1 + GLASS_PEAK_STEPS rays; a step
    that leaves the glass or meets total internal reflection keeps the axis before it
    (none: not valid). Returns (axes (N,3), valid (N,), material (N,), rays)."""
    from .closures import principled as pr
    from .geometry import SHADOW
    geo, c = ctx.geo, np.ascontiguousarray
    n = len(a)
    o = c(np.broadcast_to(centre, (n, 3)))
    ior_mat = np.maximum(np.asarray(ctx.table.closure_params, np.float64)[:, pr.M_IOR], 1e-5)
    out = np.array(a, np.float64)
    valid = np.zeros(n, bool)
    mat = np.zeros(n, np.int64)
    live = np.arange(n)
    rays = 0
    for _ in range(1 + GLASS_PEAK_STEPS):
        if not len(live):
            break
        t, prim, _, _ = ctx.accel.intersect(c(o[live]), c(out[live]), None, cls=SHADOW)
        rays += len(live)
        ok = (prim >= 0) & np.isfinite(t) & (t > 0.0)
        ok &= np.take(shades.code, np.maximum(prim, 0)) == pk.SHADE_GLASS
        live, t, prim = live[ok], t[ok], prim[ok]
        if not len(live):
            break
        m_ = np.take(np.asarray(geo.material), prim)
        ng = np.cross(np.take(geo.e1, prim, axis=0), np.take(geo.e2, prim, axis=0))
        ng /= np.linalg.norm(ng, axis=1)[:, None]
        wo = x[live] - (centre + t[:, None] * out[live])
        wo /= np.maximum(np.linalg.norm(wo, axis=1), 1e-300)[:, None]
        cos_o = np.einsum("ij,ij->i", wo, ng)
        front = cos_o > 0.0
        ior = np.take(ior_mat, m_)
        eta = np.where(front, 1.0 / ior, ior)  # n(x's side) / n(the lamp's side)
        nf = ng * np.where(front, 1.0, -1.0)[:, None]
        ci = np.abs(cos_o)
        sin2 = eta * eta * (1.0 - ci * ci)
        good = sin2 < 1.0  # (else total internal reflection: no refracted peak)
        tdir = (-eta[:, None] * wo
                + (eta * ci - np.sqrt(np.maximum(1.0 - sin2, 0.0)))[:, None] * nf)
        tdir /= np.maximum(np.linalg.norm(tdir, axis=1), 1e-300)[:, None]
        live = live[good]
        out[live] = -tdir[good]
        valid[live] = True
        mat[live] = m_[good]
    out[~valid] = a[~valid]
    return out, valid, mat, rays


def _shade_directions(a, r, a2, has2, n_pow, lobe_kind="cos"):
    """(N,3) unit directions from a lamp's centre and their solid-angle pdf (N,): where
    has2 (N,) bool, the one-sample mixture of GLASS_PEAK_SHARE of a lobe about a2 (N,3)
    (_refracted_axes: the rough glass's peak; lobe_kind "cos": cos^n_pow, "ggx": GGX's
    distribution of slope sqrt(2 / n_pow), Walter et al. 2007) and the rest
    _lamp_directions about a; elsewhere _lamp_directions alone, with the same numbers r =
    (r0, r1) as before (a scene without glass shades draws what it drew). The pdf is the mixture's
    (both strategies' densities at the direction drawn)."""
    share = GLASS_PEAK_SHARE
    peak = has2 & (r[0] < share)
    r0 = np.where(has2, np.where(peak, 0.0, (r[0] - share) / (1.0 - share)), r[0])
    w, pdf = _lamp_directions(a, (np.clip(r0, 0.0, 1.0), r[1]))
    if not has2.any():
        return w, pdf
    # The peaked lobe about a2: cos theta = v^(1 / (n + 1)) (cos^n), or GGX's
    # tan^2 theta = s^2 v / (1 - v), s = sqrt(2 / n) (its heavier tails).
    ggx_lobe = lobe_kind == "ggx"
    k = np.flatnonzero(peak)
    if len(k):
        v = np.clip(r[0][k] / share, 1e-300, 1.0)
        if ggx_lobe:
            t2 = (2.0 / n_pow[k]) * v / np.maximum(1.0 - v, 1e-300)
            ct = 1.0 / np.sqrt(1.0 + t2)
        else:
            ct = v ** (1.0 / (n_pow[k] + 1.0))
        st = np.sqrt(np.maximum(0.0, 1.0 - ct * ct))
        phi = 2.0 * math.pi * r[1][k]
        bu, bv = orthonormal_basis(a2[k])
        w[k] = ((st * np.cos(phi))[:, None] * bu + (st * np.sin(phi))[:, None] * bv
                + ct[:, None] * a2[k])
    pdf[has2] = _peak_mixture_pdf(w, a, a2, has2, n_pow, lobe_kind)
    return w, pdf


def _peak_mixture_pdf(w, a, a2, has2, n_pow, lobe_kind):
    """(H,) solid-angle pdf of _shade_directions' mixture at the unit directions w (N,3)
    from the lamp's centre, on the H rows where has2 (N,) (the other rows' pdf is
    _lamp_directions' alone): GLASS_PEAK_SHARE of the peaked lobe about a2 plus the rest
    of _lamp_directions' about a. Shared by the sampling and by the BSDF side's MIS
    weight (direction_pdf), so both read the same mixture."""
    share = GLASS_PEAK_SHARE
    ggx_lobe = lobe_kind == "ggx"
    h = np.flatnonzero(has2)
    wh = w[h]
    cos_a = np.maximum(np.einsum("ij,ij->i", wh, a[h]), 0.0)
    broad = LAMP_COSINE_SHARE * cos_a / math.pi + (1.0 - LAMP_COSINE_SHARE) * 0.25 / math.pi
    cos2 = np.maximum(np.einsum("ij,ij->i", wh, a2[h]), 0.0)
    if ggx_lobe:
        # D(theta) cos theta, D = s^2 / (pi cos^4 (s^2 + tan^2)^2) (Walter et al. 2007)
        s2 = 2.0 / n_pow[h]
        c2 = np.maximum(cos2 * cos2, 1e-300)
        t2 = np.minimum((1.0 - c2) / c2, 1e100)
        with np.errstate(divide="ignore", over="ignore"):
            lobe = np.where(cos2 > 1e-30, s2 / (math.pi * c2 * np.maximum(cos2, 1e-30)
                                                * (s2 + t2) ** 2), 0.0)
    else:
        lobe = (n_pow[h] + 1.0) / (2.0 * math.pi) * cos2 ** n_pow[h]
    return share * lobe + (1.0 - share) * broad


def shade_irradiance(ctx, shades, p, ns, ng, offset, samples, rng):
    """shade_light's irradiance alone: ((N,3) E, rays traced)."""
    E, _, rays = shade_light(ctx, shades, p, ns, ng, offset, samples, rng)
    return E, rays


def shade_light(ctx, shades, p, ns, ng, offset, samples, rng, glossy=None, used=None):
    """(N,3) irradiance at points p (N,3) (shading normals ns, geometric normals ng on the
    viewer's side, origin offsets offset (N,)) from the served lights' samples among
    `samples` (integrator.light_sample_list entries: each one's u1, u2 choose the point
    on the lamp seen from the shade) through the shades, and the shadow rays traced. rng
    (numpy Generator, the caller's seeded stream): the point on the lamp seen from y, 2
    numbers per point and sample.

    Each sample picks y where the lamp's light lands: a direction from the lamp's centre
    (_lamp_directions, about the direction to the shading point; with a rough glass
    shade, _shade_directions' mixture with a lobe about the direction the glass refracts
    towards x), y its first hit, which must be a shade triangle; the area pdf of y is
    pdf_omega cos_in / r^2 (cos_in at y's geometric normal, r the centre's distance), so
    a point lamp's E_in(y) / pdf is nearly constant and only the geometry towards x
    varies. Then the closest hit from x towards y must be y's shade at y's distance
    (shadow ray), and the lamp is sampled from y's far side (directlight.direct_light
    with the normals flipped) for y's radiance towards x: a translucent shade's T E_back
    / pi, a rough glass shade's L(y -> x) = f_t(w_lamp, w_x) L_lamp |cos| / pdf
    (principled.accumulate_transmission, the camera side's evaluation
    (engine/glasslight.py) with the view towards x, its lobes set up at y for that view:
    the Multiscatter GGX compensation on x's side, as Cycles' path from x takes it); then
    E += L(y -> x) max(N . w, 0) |n_y . w| / (d^2 pdf_A). A lamp with a radius is
    sampled over its whole size at y, but y is chosen from its centre: a shade point the
    centre cannot see (an occluder right at the lamp) is missed.

    glossy: None, or (prm (N, N_PACK), sel (N, N_LOBES), wo (N,3), mis): the points' packed
    lobes (bsdf.closures), the continuation's lobe-choice probabilities (0 where it makes
    none) and view directions; then the same samples also serve the points' rough
    reflective lobes (principled.eval_reflection, the direct light's own evaluation):
    Lg += L(y -> x) f(wo, w) cos / pdf_w(y) x w_light, pdf_w = pdf_A d^2 / |n_y . w| the
    sample's solid-angle pdf at x, w_light = (n pdf_w)^2 / ((n pdf_w)^2 + pdf_b^2) (the
    power heuristic, n the lamp's light samples, pdf_b principled.bsdf_pdf with sel: the
    continuation's; mis False: w_light 1). used: (N,) int64 the transparent bounces each
    point's camera path made (None: 0): the lamp's shadow rays from y cross Light Paths >
    Max Bounces > Transparent minus that many (directlight.direct_light's used). Returns
    ((N,3) E, (N,3) Lg (zeros without glossy), rays traced)."""
    from .bsdf import closures, surface_hit
    from .closures import principled as pr
    from .directlight import direct_light
    from .geometry import SHADOW
    from .lights.packing import pack_lights
    N = len(p)
    E = np.zeros((N, 3))
    Lg = np.zeros((N, 3))
    if N == 0 or shades is None:
        return E, Lg, 0
    packed = ctx.packed_lights or pack_lights(ctx.lights)
    geo, accel = ctx.geo, ctx.accel
    shadow = getattr(ctx, "shadow", None)
    links = getattr(ctx, "links", None)
    scale = max(float(geo.extent), 1e-9)
    rays = 0
    c = np.ascontiguousarray
    # Rough glass: each light sample at full weight (no MIS: this estimator alone counts
    # the lamp -> shade -> x paths), the lobe-choice probabilities unused.
    full = np.ones(max(len(ctx.lights), 1), np.int64)
    for li, traced, count, u1, u2, sel in samples:
        if li < 0 or li not in shades.served:
            continue
        # The direction from the lamp takes the sample's stratified numbers (u1, u2);
        # the point on the lamp seen from y, fresh ones.
        lamp_u = rng.random((2, N))
        centre, lamp_r, idx, a, peak, nr = _strategy(ctx, shades, li, p)
        rays += nr
        if not len(idx):
            continue
        if peak is not None:
            wl, pdf_w = _shade_directions(a, (u1[idx], u2[idx]), *peak)
        else:
            wl, pdf_w = _lamp_directions(a, (u1[idx], u2[idx]))
        # Where the lamp's light lands: its first hit, a shade triangle.
        o_l = c(np.broadcast_to(centre, (len(idx), 3)))
        t_l, prim, hu, hv = accel.intersect(o_l, c(wl), None, cls=SHADOW)
        rays += len(idx)
        good = (prim >= 0) & (np.take(shades.code, np.maximum(prim, 0)) < -1)
        good &= np.isfinite(t_l) & (t_l > 0.0)
        if links is not None:
            # Light Linking: the light through the shade is the shade's (Cycles lights y
            # by next-event estimation with the shade object's set; x receives it as
            # indirect light, which is not linked): none where the lamp does not light
            # the shade, whatever x's set.
            good &= links.lights_hit(li, geo, prim)
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
        seen = (prim_x >= 0) & (np.take(shades.code, np.maximum(prim_x, 0)) < -1)
        seen &= np.abs(t_hit - dist) <= 1e-3 * dist + 1e-5 * scale
        idx, wl, pdf_w, t_l, prim, hu, hv, w, dist, cr = (
            a_[seen] for a_ in (idx, wl, pdf_w, t_l, prim, hu, hv, w, dist, cr))
        if not len(idx):
            continue
        glass = np.take(shades.code, prim) == pk.SHADE_GLASS
        for on_glass in (False, True):
            part = glass if on_glass else ~glass
            if not part.any():
                continue
            if part.all():
                jdx, jl, jpdf, jt, jprim, ju, jv, jw, jdist, jcr = (
                    idx, wl, pdf_w, t_l, prim, hu, hv, w, dist, cr)
            else:
                jdx, jl, jpdf, jt, jprim, ju, jv, jw, jdist, jcr = (
                    a_[part] for a_ in (idx, wl, pdf_w, t_l, prim, hu, hv, w, dist, cr))
            # y's surface as the ray from x meets it: normals turned towards x.
            Y = surface_hit(geo, ctx.table, jprim, ju, jv, jw)
            yng = np.asarray(Y.ng, np.float64)
            cos_in = np.abs(np.einsum("ij,ij->i", jl, yng))
            cos_y = np.abs(np.einsum("ij,ij->i", jw, yng))
            # The lamp on the shade's far side: normals flipped (engine/glasslight.py).
            yns = c(-np.asarray(Y.ns, np.float64))
            arrays = (c(Y.p, np.float64), yns, _NO_ROWS3, c(-yng), c(Y.offset, np.float64),
                      _NO_ROWS, _NO_ROWS, _NO_ROWS3, yns)
            entry = [(li, traced, count, c(lamp_u[0, jdx]), c(lamp_u[1, jdx]),
                      None if sel is None else c(sel[jdx], np.float64))]
            if on_glass and GLASS_LAMP_SAMPLES > 1 and lamp_r > 0.0:
                # The point on a lamp with a radius moves the glass's peak: several per y
                # (each weighted 1 / GLASS_LAMP_SAMPLES by direct_light's sample count).
                more = rng.random((2 * (GLASS_LAMP_SAMPLES - 1), len(jdx)))
                u_1 = [entry[0][3]] + [more[2 * j - 2] for j in range(1, GLASS_LAMP_SAMPLES)]
                u_2 = [entry[0][4]] + [more[2 * j - 1] for j in range(1, GLASS_LAMP_SAMPLES)]
                if GLASS_LAMP_STRATIFIED:
                    # Jittered strata of the lamp's sampling square (each point still
                    # uniform: unbiased), the same numbers as the jitters.
                    nx, ny = _strata(GLASS_LAMP_SAMPLES)
                    u_1 = [(j % nx + u) / nx for j, u in enumerate(u_1)]
                    u_2 = [(j // nx + u) / ny for j, u in enumerate(u_2)]
                entry = [(li, traced, count * GLASS_LAMP_SAMPLES, c(u_1[j]), c(u_2[j]), e[5])
                         for e in entry for j in range(GLASS_LAMP_SAMPLES)]
            pdf_a = jpdf * cos_in / (jt * jt)
            if on_glass:
                # L(y -> x): the glass lobes set up for the view towards x.
                prm, _ = closures(ctx.table, Y, geo)
                transmission = (c(prm), c(Y.ns, np.float64), c(Y.wo, np.float64), full,
                                np.zeros((len(jdx), pr.N_LOBES)))
                Ly, nr = direct_light(packed, arrays, entry, accel, SHADOW, len(jdx),
                                      shadow=shadow, transmission=transmission,
                                      used=None if used is None else used[jdx])
                rays += nr
            else:
                Eb, nr = direct_light(packed, arrays, entry, accel, SHADOW, len(jdx),
                                      shadow=shadow,
                                      used=None if used is None else used[jdx])
                rays += nr
                Ly = shades.tl[np.asarray(Y.mat)] * Eb / math.pi  # T E_back / pi
            g = jcr * cos_y / (jdist * jdist * np.maximum(pdf_a, 1e-300))
            E[jdx] += Ly * g[:, None]
            if glossy is not None:
                # x's rough reflective lobes towards y, by the direct light's evaluation
                # (f cos at x), over y's solid-angle pdf at x, MIS-weighted against the
                # continuation that meets the shade (shade_bsdf_weights: its side).
                gp, gsel, gwo, mis = glossy
                prm_x = c(gp[jdx])
                fr = np.empty((len(jdx), 3))
                pr.eval_reflection_many(prm_x, c(ns[jdx]), c(gwo[jdx]), c(jw), fr)
                pdf_x = np.maximum(pdf_a, 1e-300) * jdist * jdist / np.maximum(cos_y, 1e-300)
                wgt = 1.0 / pdf_x
                if mis:
                    pb = np.empty(len(jdx))
                    pr.bsdf_pdf_many(prm_x, c(gsel[jdx]), c(ns[jdx]), c(gwo[jdx]), c(jw), pb)
                    pl = count * pdf_x
                    wgt = wgt * (pl * pl / (pl * pl + pb * pb))
                Lg[jdx] += Ly * fr * wgt[:, None]
    return E, Lg, rays


def _strata(n):
    """(nx, ny), nx * ny = n, the most nearly square grid (nx >= ny)."""
    ny = int(math.isqrt(n))
    while n % ny:
        ny -= 1
    return n // ny, ny


def _strategy(ctx, shades, li, p):
    """How the shade samples of served light li are drawn for the points p (N,3): (centre
    (3,), lamp radius, idx (K,) the points far enough from the centre, a (K,3) their unit
    directions from it, peak: None (_lamp_directions) or the glass peak's
    (a2, has2, n_pow, lobe_kind) for _shade_directions, rays traced (_refracted_axes)).
    The light side (shade_light) and the BSDF side's weights (shade_bsdf_weights) both
    take it, so each reads the other's pdf."""
    from .closures import principled as pr
    light = ctx.lights[li]
    centre = np.asarray(light.pos, np.float64).reshape(3)
    lamp_r = float(getattr(light, "radius", 0.0) or 0.0)
    scale = max(float(ctx.geo.extent), 1e-9)
    to_x = p - centre
    dx = np.sqrt(np.einsum("ij,ij->i", to_x, to_x))
    idx = np.flatnonzero(dx > 1e-9 * scale)
    a = to_x[idx] / dx[idx, None]
    if not (len(idx) and shades.has_glass and GLASS_PEAK_SHARE > 0.0
            and shades.near_glass(centre)):
        return centre, lamp_r, idx, a, None, 0
    rough = np.asarray(ctx.table.closure_params, np.float64)[:, pr.M_ROUGH]
    alpha_mat = np.maximum(rough * rough, 1e-3)
    a2, has2, mat0, nr = _refracted_axes(ctx, shades, centre, a, p[idx])
    # (the peaked lobe's spread: of the glass the lamp's ray towards x meets)
    kind = GLASS_PEAK_LOBE or ("ggx" if lamp_r == 0.0 else "cos")
    spread = GLASS_PEAK_WIDTH * GLASS_PEAK_BASE[kind] * np.take(alpha_mat, mat0)
    return centre, lamp_r, idx, a, (a2, has2, 2.0 / spread ** 2, kind), nr


def direction_pdf(w, a, peak):
    """(K,) solid-angle pdf with which the shade samples (_strategy's a, peak) draw the
    unit directions w (K,3) from the lamp's centre: _lamp_directions' mixture, or with a
    glass peak _shade_directions'."""
    cos_a = np.maximum(np.einsum("ij,ij->i", w, a), 0.0)
    pdf = LAMP_COSINE_SHARE * cos_a / math.pi + (1.0 - LAMP_COSINE_SHARE) * 0.25 / math.pi
    if peak is not None and peak[1].any():
        pdf[peak[1]] = _peak_mixture_pdf(w, a, *peak)
    return pdf


def shade_bsdf_weights(ctx, shades, x, x_ns, o, d, t, prim, pdf_b):
    """The BSDF side of the glossy lobes' MIS (shade_light's glossy): for K continuation
    rays from camera points x (K,3) (shading normals x_ns (K,3)) whose glossy lobes took
    the shade samples, leaving from o (K,3) along d (K,3) with pdf pdf_b (K,) (the
    continuation's, principled.bsdf_pdf; inf: a mirror-like lobe) and meeting triangle
    prim (K,) at distance t (K,): ((K, L) weights of each light's light through the shade
    met there, (the power heuristic pdf_b^2 / (pdf_b^2 + (n pdf_w)^2), pdf_w the shade
    sample's solid-angle pdf at x of that point, n the light's samples; 1 for lights not
    served, rows not on a shade, mirror-like lobes and points the shade samples cannot
    draw), rays traced). The point y = o + t d must be the first hit from the lamp's
    centre towards it, as where shade_light's lamp-side ray lands."""
    from .geometry import SHADOW
    K = len(x)
    W = np.ones((K, max(len(ctx.lights), 1)))
    rays = 0
    on = (prim >= 0) & np.isfinite(pdf_b) & np.isfinite(t)
    on &= np.take(shades.code, np.maximum(prim, 0)) < -1
    rows = np.flatnonzero(on)
    if not len(rows):
        return W, rays
    geo = ctx.geo
    c = np.ascontiguousarray
    scale = max(float(geo.extent), 1e-9)
    y = o[rows] + t[rows, None] * d[rows]
    w = d[rows]
    dist = t[rows]
    cr = np.einsum("ij,ij->i", w, x_ns[rows])
    yng = np.cross(np.take(geo.e1, prim[rows], axis=0), np.take(geo.e2, prim[rows], axis=0))
    yng /= np.maximum(np.linalg.norm(yng, axis=1), 1e-300)[:, None]
    cos_y = np.abs(np.einsum("ij,ij->i", w, yng))
    ok = (cr > 0.0) & (dist > 1e-6 * scale) & (cos_y > 0.0)
    for li in sorted(shades.served):
        plan = getattr(ctx, "plan", None)  # (None: one sample, as a bare estimator call)
        n_l = 1 if plan is None else plan.light_samples.get(ctx.lights[li].name, 1)
        centre, _, idx, a, peak, nr = _strategy(ctx, shades, li, x[rows])
        rays += nr
        if not len(idx):
            continue
        to_y = y[idx] - centre
        r = np.sqrt(np.einsum("ij,ij->i", to_y, to_y))
        wl = to_y / np.maximum(r, 1e-300)[:, None]
        pdf_w = direction_pdf(wl, a, peak)
        # y must be where the lamp-side ray lands: its first hit from the centre.
        t_l, prim_l, _, _ = ctx.accel.intersect(c(np.broadcast_to(centre, (len(idx), 3))),
                                                c(wl), None, cls=SHADOW)
        rays += len(idx)
        land = (prim_l == prim[rows][idx]) & np.isfinite(t_l)
        land &= np.abs(t_l - r) <= 1e-3 * r + 1e-5 * scale
        cos_in = np.abs(np.einsum("ij,ij->i", wl, yng[idx]))
        pdf_a = pdf_w * cos_in / np.maximum(r * r, 1e-300)
        pl = n_l * pdf_a * dist[idx] ** 2 / np.maximum(cos_y[idx], 1e-300)
        pl = np.where(land & ok[idx], pl, 0.0)
        pb = pdf_b[rows][idx]
        with np.errstate(invalid="ignore", over="ignore"):
            wb = np.nan_to_num(pb * pb / (pb * pb + pl * pl), nan=1.0)
        W[rows[idx], li] = wb
    return W, rays
