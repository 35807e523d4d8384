"""Random-walk subsurface scattering of camera paths, as Cycles' Random Walk BSSRDF.

A camera path (or a camera chain through mirrors and glass) that hits a surface with a
subsurface closure (Principled Subsurface Weight > 0, or the Subsurface Scattering node)
splits the diffuse lobe Cycles builds there into its two closures (Cycles svm_closure.h,
Principled: diffuse weight (1 - w) c L, BSSRDF weight w c L, with c the Base Color
clamped to [0, 1] and L the layering of the coat / sheen / specular lobes above):
  - the diffuse part is shaded at the hit as before;
  - the BSSRDF part walks beneath the surface (Cycles kernel/integrator/subsurface.h
    subsurface_bounce, subsurface_random_walk.h subsurface_random_walk):
      entry     a GGX refraction (VNDF-sampled microfacet normal of alpha = roughness^2,
                relative index 1 / IOR; the Principled's IOR, the node's own) about the
                BSSRDF's normal: Cycles' bssrdf->N, the shading normal turned towards
                the geometric one where the viewer's mirror direction would fall below
                the surface (maybe_ensure_valid_specular_reflection, as the glossy lobes':
                bssrdf_normals), rejected where the direction would leave through the
                geometric normal's side (DIFFUSE_ENTRY: the share Cycles' newer source
                enters by a cosine-distributed direction about -N instead; 0 measures as
                bpy 5.0's Cycles);
      medium    per channel sigma_t and single-scattering albedo alpha from Cycles'
                fit (subsurface_random_walk_remap: radius = Radius x Scale x 1/(4 pi),
                the Base Color as the multiple-scattering albedo, anisotropy g); the
                throughput starts at w L (the closure weight over the albedo), alpha
                below 0.2 raised to 0.2 with the throughput scaled by alpha / 0.2;
      steps     a channel drawn in proportion to throughput x alpha, an exponential free
                flight of that channel's sigma_t, one closest-hit query against the
                object's own triangles (Cycles' scene_intersect_local), throughput x
                (hit ? T : sigma_s T) / sum_c(channel_pdf_c pdf_c) (one-sample MIS over
                the three channels); Henyey-Greenstein directions of g for the first
                SIMILARITY_LEVEL scatters, isotropic with the similarity-scaled
                sigma_s (1 - g) after them; at most BSSRDF_MAX_BOUNCES steps (beyond:
                absorbed), dropped below VOLUME_THROUGHPUT_EPSILON;
      exit      the walk's exit point is shaded as a Lambertian surface of weight 1 (its
                interpolated shading normal seen from outside, as it is: Cycles'
                subsurface_shader_data_setup; not replaced by the face's normal where
                the walk's direction leaves below it), lit by the usual next-event
                estimate and the photon / final-gather estimates, times the walk's
                throughput.
(BSSRDF_NORMALS: on a Shade Smooth cylinder's flat cap, whose interpolated normals lean
towards the rim, the entry on the shading normal itself started no walk where that
normal faces away from the viewer, the exits' guard dimmed the side; the candle of
docs/accuracy.md's studio48 read 0.818 of Cycles on its cap, 0.995 now: subsurf49.)
Cycles mixes classic free-flight sampling with Dwivedi-guided sampling by MIS (variance
reduction only, the same expectation); both are here with Cycles' MIS weights.

Two implementations of the same estimator: walk_rows, a compiled kernel that steps each
walk to its end calling Embree itself (accel._intersect_rows; the default), and the numpy
steps in walk() (one Embree call per step for the whole batch: a Python iteration per
step, up to 256 of them because a few walks go long; used where the kernel's Embree entry
is missing, or with USE_COMPILED False). tests/test_subsurface_walk.py checks that both
reflect and transmit alike.

Photons and final-gather rays keep the diffuse stand-in (engine/subsurface.py): light
that reaches a subsurface surface after a diffuse bounce sees the albedo Cycles'
random walk gives a thick object of the Base Color. (Cycles itself turns a BSSRDF after a
diffuse ancestor into a Lambertian of weight w c: bssrdf_setup's PATH_RAY_DIFFUSE_ANCESTOR.
The stand-in differs from that by c - A(c): 0.01 at c = 0.8, 0.03 at 0.5, 0.09 at 1; it is
kept so that the photon pass stays the same with the walk on or off.)

A textured Base Color or a texture-driven Subsurface Weight walks too (ssstex41): the
material's SubsurfaceParams carry the colour and weight nodes, evaluated at each walk's
entry as the surface's textures are (SubsurfaceWalks.entries), and each walk's medium is
fitted from its own albedo (coefficients is per row); a textured Subsurface Radius
likewise gives each walk its own radius. A textured Scale keeps the socket's value
(warned at export).
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np

from .accel import _intersect_rows
from .closures import principled as pr
from .jit import kernel, register_warm_up

# Cycles' constants (kernel/types.h, kernel/integrator/subsurface_random_walk.h).
BSSRDF_MAX_BOUNCES = 256
BSSRDF_MIN_RADIUS = 1e-8
VOLUME_THROUGHPUT_EPSILON = 1e-6
SIMILARITY_LEVEL = 9
MIN_ALPHA = 0.2
# Walks stepped by the compiled kernel walk_rows (Embree called from it); False: the numpy
# steps (one Embree call per step for the batch), also taken where the kernel's Embree
# entry is not available.
USE_COMPILED = True
# The share of walks that enter by a cosine-distributed direction instead of the GGX
# refraction. Cycles' newer source (subsurface_entry_bounce) gives Random Walk 0.5; the
# Cycles in the bpy 5.0 wheel refracts every walk: a 2 cm white slab (radius 5 cm x
# 1/(4 pi)) lit straight on reflects R = 0.734 and transmits T = 0.257 in Cycles; this walk
# gives R 0.735, T 0.256 with 0 and R 0.760, T 0.232 with 0.5 (docs/accuracy.md, sss41).
DIFFUSE_ENTRY = 0.0
# Cycles' normals at the walk's ends (subsurf49): the entry refracts about the BSSRDF's
# normal (bssrdf_normals: the shading normal turned as the glossy lobes'), the exit's
# Lambertian takes its interpolated normal unguarded. False: the entry about the hit's
# shading normal, the exits' normals guarded (before subsurf49; for A/B runs).
BSSRDF_NORMALS = True


@dataclass(frozen=True)
class SubsurfaceParams:
    """One material's BSSRDF (Cycles' Bssrdf closure): weight w (Subsurface Weight, 1 for
    the Subsurface Scattering node), color c (3,) the Base Color / Color (albedo, clamped
    to [0, 1]), radius (3,) Radius x Scale in metres (before Cycles' 1/(4 pi)), ior (the
    entry's refraction, clamped to [1.01, 3.8]), anisotropy (clamped to [0, 0.9]),
    roughness (the entry's GGX alpha = roughness^2)."""
    weight: float
    color: tuple
    radius: tuple
    ior: float = 1.5
    anisotropy: float = 0.0
    roughness: float = 1.0
    # Per-hit inputs (engine/shadernodes.py nodes, evaluate(geo, prim, u, v)), or None for
    # the constants above: the Base Color / Color (before clamping) and the Subsurface
    # Weight. (Compared as the nodes compare; left out of the hash: not every node is
    # hashable.)
    color_node: object = field(default=None, hash=False)
    weight_node: object = field(default=None, hash=False)
    # Radius x Scale per hit (a node, metres, before Cycles' 1/(4 pi)), or None: radius.
    radius_node: object = field(default=None, hash=False)

    @classmethod
    def make(cls, weight, color, radius, ior, anisotropy, roughness, color_node=None,
             weight_node=None, radius_node=None) -> "SubsurfaceParams":
        return cls(float(min(max(weight, 0.0), 1.0)),
                   tuple(float(x) for x in np.clip(np.asarray(color, float)[:3], 0.0, 1.0)),
                   tuple(float(max(x, 0.0)) for x in np.asarray(radius, float)[:3]),
                   float(min(max(ior, 1.01), 3.8)), float(min(max(anisotropy, 0.0), 0.9)),
                   float(min(max(roughness, 0.0), 1.0)), color_node, weight_node,
                   radius_node)

    @property
    def textured(self) -> bool:
        """Whether the colour, the weight or the radius is evaluated per hit."""
        return (self.color_node is not None or self.weight_node is not None
                or self.radius_node is not None)

    def per_hit(self, geo, prim, u, v):
        """(c (N,3) clamped to [0, 1], w (N,) clamped to [0, 1], radius (N,3) >= 0) at N
        hits: the nodes' values (geo a shadernodes.ShadingGeometry of the hits for
        view-dependent nodes), the constants where no node drives them."""
        from .shadernodes import _eval
        n = len(prim)
        c = (np.tile(np.asarray(self.color, np.float64), (n, 1)) if self.color_node is None
             else np.clip(np.nan_to_num(_eval(self.color_node, geo, prim, u, v, 3)[:, :3],
                                        nan=0.0), 0.0, 1.0))
        w = (np.full(n, self.weight) if self.weight_node is None
             else np.clip(np.nan_to_num(_eval(self.weight_node, geo, prim, u, v, 1),
                                        nan=0.0), 0.0, 1.0))
        r = (np.tile(np.asarray(self.radius, np.float64), (n, 1)) if self.radius_node is None
             else np.maximum(np.nan_to_num(_eval(self.radius_node, geo, prim, u, v, 3)[:, :3],
                                           nan=0.0), 0.0))
        return c, w, r

    def stand_in(self) -> np.ndarray:
        """The diffuse colour standing in for this surface where it does not walk
        (engine/subsurface.diffuse_color)."""
        from .subsurface import diffuse_color
        return diffuse_color(np.asarray(self.color), self.weight)


def remap(albedo, d, g):
    """Cycles' subsurface_random_walk_remap, element-wise: (sigma_t, alpha) of a medium
    whose multiple-scattering albedo is `albedo` at mean free path d (metres) and
    Henyey-Greenstein anisotropy g (a fit: Chiang, Kutz, Burley 2016, with Wrenninge et
    al.'s anisotropic terms). Arrays broadcast together."""
    albedo = np.asarray(albedo, np.float64)
    g = np.asarray(g, np.float64)
    g2 = g * g
    g3 = g2 * g
    g4, g5, g6, g7 = g2 * g2, g2 * g3, g3 * g3, g3 * g2 * g2
    A = (1.8260523782 - 1.28451056436 * g - 1.79904629312 * g2 + 9.19393289202 * g3
         - 22.8215585862 * g4 + 32.0234874259 * g5 - 23.6264803333 * g6 + 7.21067002658 * g7)
    B = 4.98511194385 + 0.127355959438 * np.exp(
        31.1491581433 * g - 201.847017512 * g2 + 841.576016723 * g3 - 2018.09288505 * g4
        + 2731.71560286 * g5 - 1935.41424244 * g6 + 559.009054474 * g7)
    C = (1.09686102424 - 0.394704063468 * g + 1.05258115941 * g2 - 8.83963712726 * g3
         + 28.8643230661 * g4 - 46.8802913581 * g5 + 38.5402837518 * g6 - 12.7181042538 * g7)
    D = (0.496310210422 + 0.360146581622 * g - 2.15139309747 * g2 + 17.8896899217 * g3
         - 55.2984010333 * g4 + 82.065982243 * g5 - 58.5106008578 * g6 + 15.8478295021 * g7)
    E = 4.23190299701 + 0.00310603949088 * np.exp(
        76.7316253952 * g - 594.356773233 * g2 + 2448.8834203 * g3 - 5576.68528998 * g4
        + 7116.60171912 * g5 - 4763.54467887 * g6 + 1303.5318055 * g7)
    F = (2.40602999408 - 2.51814844609 * g + 9.18494908356 * g2 - 79.2191708682 * g3
         + 259.082868209 * g4 - 403.613804597 * g5 + 302.85712436 * g6 - 87.4370473567 * g7)
    blend = albedo ** 0.25
    alpha = ((1.0 - blend) * A * np.arctan(B * albedo) ** C
             + blend * D * np.arctan(E * albedo) ** F)
    alpha = np.clip(alpha, 0.0, 0.999999)
    sigma_t = 1.0 / np.maximum(np.asarray(d, np.float64), 1e-16) / (1.0 - g)
    return sigma_t, alpha


def coefficients(albedo, radius, g):
    """Cycles' subsurface_random_walk_coefficients for N walks: albedo, radius (N,3)
    (radius already x 1/(4 pi)), g (N,) -> sigma_t, alpha (N,3) and the factor (N,3)
    on the throughput: 1 / albedo (0 where the albedo is 0), x alpha / MIN_ALPHA where
    alpha was raised to MIN_ALPHA."""
    albedo = np.asarray(albedo, np.float64)
    sigma_t, alpha = remap(albedo, radius, np.asarray(g, np.float64)[:, None])
    factor = np.divide(1.0, albedo, out=np.zeros_like(albedo), where=albedo != 0)
    low = alpha < MIN_ALPHA
    factor = np.where(low, factor * alpha / MIN_ALPHA, factor)
    alpha = np.where(low, MIN_ALPHA, alpha)
    return sigma_t, alpha, factor


def _frame(n):
    """Orthonormal tangents (T, B) (N,3) about unit normals n (N,3) (Frisvad / Duff)."""
    sign = np.where(n[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + sign * n[:, 0] * n[:, 0] * a, sign * b, -sign * n[:, 0]], axis=1)
    bt = np.stack([b, sign + n[:, 1] * n[:, 1] * a, -n[:, 1]], axis=1)
    return t, bt


def _around(axis, cos_t, phi):
    """Unit directions at angle acos(cos_t), azimuth phi about unit axes (N,3)."""
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    t, b = _frame(axis)
    return ((sin_t * np.cos(phi))[:, None] * t + (sin_t * np.sin(phi))[:, None] * b
            + cos_t[:, None] * axis)


def henyey_greenstein(d, g, u1, u2):
    """Directions scattered from propagation directions d (N,3) by Henyey-Greenstein of
    anisotropy g (N,) (g > 0 forward), u1, u2 (N,) uniform numbers (Cycles'
    henyey_greenstrein_sample's inversion)."""
    g = np.asarray(g, np.float64)
    iso = np.abs(g) < 1e-3
    gs = np.where(iso, 0.5, g)
    k = (1.0 - gs * gs) / (1.0 - gs + 2.0 * gs * u1)
    cos_t = np.where(iso, 1.0 - 2.0 * u1, (1.0 + gs * gs - k * k) / (2.0 * gs))
    return _around(d, np.clip(cos_t, -1.0, 1.0), 2.0 * math.pi * u2)


def entry_directions(n, ng, wi, alpha, ior, u, diffuse_share=None):
    """Cycles' subsurface_entry_bounce for CLOSURE_BSSRDF_RANDOM_WALK_ID: directions
    (N,3) into the surface and a mask (N,) of the walks that start. n the BSSRDF normal
    (shading normal on the viewer's side), ng the geometric normal on that side, wi the
    direction to the viewer, alpha (N,) the GGX roughness of the refractive entry, ior
    (N,), u (N,3) uniform numbers (u[:,0] picks: below diffuse_share (None:
    DIFFUSE_ENTRY) a cosine-distributed direction about -n, else a VNDF-sampled GGX
    refraction, each reusing u[:,0] rescaled)."""
    share = DIFFUSE_ENTRY if diffuse_share is None else float(diffuse_share)
    m = len(n)
    wo = np.empty((m, 3))
    diffuse = u[:, 0] < share
    ok = np.ones(m, np.bool_)
    if diffuse.any():
        r = np.flatnonzero(diffuse)
        u1 = u[r, 0] / share
        cos_t = np.sqrt(1.0 - u1)  # cosine-weighted: cos^2 = 1 - u
        wo[r] = _around(-n[r], cos_t, 2.0 * math.pi * u[r, 1])
    r = np.flatnonzero(~diffuse)
    if len(r):
        u1 = (u[r, 0] - share) / (1.0 - share)
        nn, w = n[r], wi[r]
        a = np.maximum(alpha[r], 1e-7)
        cos_ni = np.einsum("ij,ij->i", nn, w)
        t, b = _frame(nn)
        lx, ly = np.einsum("ij,ij->i", t, w), np.einsum("ij,ij->i", b, w)
        # Heitz 2018, "Sampling the GGX Distribution of Visible Normals".
        vh = np.stack([a * lx, a * ly, cos_ni], axis=1)
        vh /= np.maximum(np.linalg.norm(vh, axis=1), 1e-300)[:, None]
        lensq = vh[:, 0] ** 2 + vh[:, 1] ** 2
        inv = np.where(lensq > 0, 1.0 / np.sqrt(np.maximum(lensq, 1e-300)), 0.0)
        t1 = np.where(lensq[:, None] > 0,
                      np.stack([-vh[:, 1] * inv, vh[:, 0] * inv, np.zeros(len(r))], axis=1),
                      np.array([1.0, 0.0, 0.0]))
        t2 = np.cross(vh, t1)
        rr = np.sqrt(u1)
        phi = 2.0 * math.pi * u[r, 1]
        p1, p2 = rr * np.cos(phi), rr * np.sin(phi)
        s = 0.5 * (1.0 + vh[:, 2])
        p2 = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - p1 * p1)) + s * p2
        nh = (p1[:, None] * t1 + p2[:, None] * t2
              + np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))[:, None] * vh)
        hl = np.stack([a * nh[:, 0], a * nh[:, 1], np.maximum(nh[:, 2], 0.0)], axis=1)
        hl /= np.maximum(np.linalg.norm(hl, axis=1), 1e-300)[:, None]
        h = hl[:, 0:1] * t + hl[:, 1:2] * b + hl[:, 2:3] * nn
        neta = 1.0 / ior[r]
        cos_hi = np.einsum("ij,ij->i", h, w)
        arg = 1.0 - neta * neta * (1.0 - cos_hi * cos_hi)
        dnp = np.maximum(np.sqrt(np.maximum(arg, 0.0)), 1e-7)
        nk = neta * cos_hi - dnp
        wo[r] = -neta[:, None] * w + nk[:, None] * h
        ok[r] = cos_ni > 0.0
    norm = np.linalg.norm(wo, axis=1)
    wo /= np.where(norm > 0, norm, 1.0)[:, None]
    ok &= np.einsum("ij,ij->i", ng, wo) < 0.0
    return wo, ok


@kernel
def bssrdf_normals(ns, ng, wo, out):
    """Cycles' BSSRDF normal at N entries (svm/closure.h: bssrdf->N =
    maybe_ensure_valid_specular_reflection(sd, N), the normal the entry's refraction
    turns about): the shading normal ns (N,3) turned towards the geometric normal ng
    (N,3) (both on the viewer's side) just enough that the mirror direction of the
    unit view direction wo (N,3) about it rises above the surface
    (principled.valid_reflection_normal, as the glossy lobes' normal), or ns itself;
    written to out (N,3), unit."""
    for i in range(ns.shape[0]):
        raised, p0, p1, p2 = pr.valid_reflection_normal(ns[i, 0], ns[i, 1], ns[i, 2],
                                                        ng[i, 0], ng[i, 1], ng[i, 2],
                                                        wo[i, 0], wo[i, 1], wo[i, 2])
        ln = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
        if raised and ln > 0.0:
            out[i, 0], out[i, 1], out[i, 2] = p0 / ln, p1 / ln, p2 / ln
        else:
            out[i, 0], out[i, 1], out[i, 2] = ns[i, 0], ns[i, 1], ns[i, 2]


class ObjectMeshes:
    """Each walking object's own triangles in an Embree BVH (Cycles' local intersection:
    a walk meets only its object's surface), built on first use; thread-safe."""

    def __init__(self, geo):
        self.geo = geo
        self._accels = {}
        self._lock = threading.Lock()

    def get(self, obj: int):
        """(Accel over object obj's triangles, (K,) int64 their global rows)."""
        with self._lock:
            got = self._accels.get(obj)
            if got is None:
                from .accel import Accel
                rows = np.flatnonzero(np.asarray(self.geo.object_id) == obj).astype(np.int64)
                v0 = np.asarray(self.geo.v0, np.float64)[rows]
                verts = np.concatenate([v0, v0 + np.asarray(self.geo.e1, np.float64)[rows],
                                        v0 + np.asarray(self.geo.e2, np.float64)[rows]])
                k = len(rows)
                faces = np.stack([np.arange(k), np.arange(k) + k, np.arange(k) + 2 * k], axis=1)
                got = (Accel(verts, faces, threads=1), rows)
                self._accels[obj] = got
            return got


def walk(meshes: ObjectMeshes, obj, p, n, ng, wi, offset, sp: list, rng, stats=None,
         albedo=None, radius=None, n_entry=None):
    """Random walks from M entry points. obj (M,) the entry triangles' objects; p, n, ng,
    wi (M,3) the entry point, BSSRDF normal, geometric normal (both on the viewer's side)
    and the direction to the viewer; offset (M,) the entry's ray-origin offset; sp (M,)
    SubsurfaceParams; rng a numpy Generator. Returns (ok (M,) bool: the walk left through
    the surface, prim (M,) int64 global exit triangle, u, v (M,), d (M,3) the exit
    direction (outwards), throughput (M,3): the walk's weight per unit closure weight
    over the albedo (Cycles' throughput / (w L))). stats: None, or a dict whose "rays"
    entry is increased by the rays the walks cast. albedo: None (each walk's sp.color),
    or (M,3) in [0, 1] each walk's own (a textured Base Color at its entry); radius:
    None (sp.radius) or (M,3) each walk's Radius x Scale (metres). n_entry: None (n), or
    (M,3) the unit normals the entry refracts about (Cycles' bssrdf->N: bssrdf_normals);
    n stays the walk's guiding normal (the hit's shading normal; Cycles guides about
    bssrdf->N too, which differs from n only where bssrdf_normals turned it: sampling
    alone, since the MIS pdfs take the same n, so the mean is the same)."""
    m = len(p)
    albedo = (np.array([s.color for s in sp], np.float64).reshape(m, 3) if albedo is None
              else np.asarray(albedo, np.float64).reshape(m, 3))
    radius = (np.array([s.radius for s in sp], np.float64).reshape(m, 3) if radius is None
              else np.asarray(radius, np.float64).reshape(m, 3)) * (0.25 / math.pi)
    g = np.array([s.anisotropy for s in sp], np.float64)
    ior = np.array([s.ior for s in sp], np.float64)
    alpha_ggx = np.array([s.roughness for s in sp], np.float64) ** 2
    d, ok = entry_directions(n if n_entry is None else n_entry, ng, wi, alpha_ggx, ior,
                             rng.random((m, 3)))
    # Channels whose radius is too small for the walk (Cycles: a diffuse closure of their
    # weight instead) are out of the walk; the caller shades them at the entry.
    sigma_t, alpha, tp = coefficients(albedo, np.maximum(radius, 1e-16), g)
    # (The caller's weights are the closure weight over the albedo already: only the
    # low-alpha factor is kept, and a channel of albedo 0 walks with weight 0.)
    tp *= albedo
    sigma_s = sigma_t * alpha
    # The similarity relation past SIMILARITY_LEVEL scatters: isotropic, sigma_s (1 - g).
    sigma_s_star = sigma_s * (1.0 - g)[:, None]
    sigma_t_star = sigma_t - sigma_s + sigma_s_star
    out_prim = np.full(m, -1, np.int64)
    out_u, out_v = np.zeros(m), np.zeros(m)
    out_d = np.zeros((m, 3))
    done = np.zeros(m, np.bool_)
    # Dwivedi guiding (Cycles: Krivanek & d'Eon 2014, Meng et al. 2016, d'Eon & Krivanek
    # 2020): directions drawn about the entry normal away from (or, near an opposite
    # side found by the first ray, towards) the surface, distances stretched to match,
    # combined with the classic sampling by MIS; the highest alpha sets the length v.
    amax = alpha.max(axis=1)
    v_len = 1.0 / np.sqrt(np.maximum(
        1.0 - amax ** (2.44294 - 0.0215813 * amax + 0.578637 / amax), 1e-300))
    ok &= v_len != 1.0  # (Cycles gives up there: an infinite phase function)
    v_len = np.where(v_len > 1.0, v_len, 1.0 + 1e-7)
    phase_log = np.log((v_len + 1.0) / (v_len - 1.0))
    guided_org = 1.0 - np.maximum(0.5, np.abs(g) ** 0.125)
    opposite = np.zeros(m, np.bool_)
    opposite_distance = np.zeros(m)
    # Start just inside the surface (off the entry triangle along -ng).
    p0 = p
    pos = p - ng * offset[:, None]
    live = np.flatnonzero(ok)
    compiled = _compiled_walk(meshes, obj, live) if USE_COMPILED else None
    if compiled is not None:
        # Each walk stepped through Embree inside one kernel (walk_rows), by object.
        seeds = rng.integers(0, np.iinfo(np.int64).max, m, dtype=np.int64).astype(np.uint64)
        rays = np.zeros(1, np.int64)
        c = np.ascontiguousarray  # (the kernel's one signature: C-ordered float64 rows)
        pos, d, tp = c(pos, np.float64), c(d, np.float64), c(tp, np.float64)
        args = (c(n, np.float64), c(p0, np.float64), c(sigma_t), c(sigma_s), c(sigma_t_star),
                c(sigma_s_star), c(alpha), c(g, np.float64), c(guided_org), c(v_len),
                c(phase_log), tp, seeds, out_prim, out_u, out_v, out_d, done, rays)
        for fn, scene, starts, rows, sel in compiled:
            walk_rows(fn, scene, c(starts, np.int64), c(rows, np.int64), sel, pos, d, *args)
        if stats is not None:
            stats["rays"] = stats.get("rays", 0) + int(rays[0])
        live = live[:0]
    for bounce in range(BSSRDF_MAX_BOUNCES):
        if not len(live):
            break
        k = len(live)
        if stats is not None:
            stats["rays"] = stats.get("rays", 0) + k
        late = bounce > SIMILARITY_LEVEL
        st = sigma_t_star[live] if late else sigma_t[live]
        ss = sigma_s_star[live] if late else sigma_s[live]
        u = rng.random((k, 7))
        # Channel pick in proportion to throughput x alpha (volume_sample_channel).
        wts = tp[live] * alpha[live]
        tot = wts.sum(axis=1)
        cpdf = np.where(tot[:, None] > 0, wts / np.where(tot > 0, tot, 1.0)[:, None], 1.0 / 3)
        cdf = np.cumsum(cpdf, axis=1)
        ch = np.minimum((u[:, 0:1] >= cdf[:, :2]).sum(axis=1), 2)
        sample_st = st[np.arange(k), ch]
        if bounce > 0:
            gl = np.zeros(k) if late else g[live]
            gf = np.full(k, 0.75) if late else guided_org[live]
            guided = u[:, 2] < gf
            nl, v, plog = n[live], v_len[live], phase_log[live]
            opp, odist = opposite[live], opposite_distance[live]
            x = np.clip(np.einsum("ij,ij->i", pos[live] - p0[live], -nl), 0.0, odist)
            back_frac = np.where(opp, 1.0 / (1.0 + np.exp((odist - 2.0 * x) / v)), 0.0)
            backward = opp & (u[:, 3] < back_frac)
            d_old = d[live]
            d_new = henyey_greenstein(d_old, gl, u[:, 4], u[:, 5])
            cos_t = np.einsum("ij,ij->i", d_new, nl)
            if guided.any():
                gi = np.flatnonzero(guided)
                c = v[gi] - (v[gi] + 1.0) * np.exp(-u[gi, 4] * plog[gi])
                c = np.where(backward[gi], -c, c)
                d_new[gi] = _around(nl[gi], np.clip(c, -1.0, 1.0), 2.0 * math.pi * u[gi, 5])
                cos_t[gi] = c
            hg = _hg_pdf(np.einsum("ij,ij->i", d_old, d_new), gl)
            fwd_factor = (0.5 / math.pi) / ((v - cos_t) * plog) / hg
            bwd_factor = (0.5 / math.pi) / ((v + cos_t) * plog) / hg
            fwd_stretch = 1.0 - cos_t / v
            bwd_stretch = 1.0 + cos_t / v
            sample_st = np.where(guided, sample_st * np.where(backward, bwd_stretch,
                                                              fwd_stretch), sample_st)
            d[live] = d_new
        t = -np.log1p(-u[:, 1]) / sample_st
        if bounce == 0:
            # The first ray looks 10 mean free paths ahead for an opposite side.
            reach = np.maximum(t, 10.0 / st.min(axis=1))
            th, prim, hu, hv = _intersect(meshes, obj[live], pos[live], d[live], reach)
            found = prim >= 0
            opposite[live] = found
            far = pos[live] + np.where(found, th, 0.0)[:, None] * d[live]
            opposite_distance[live] = np.where(
                found, np.einsum("ij,ij->i", far - p0[live], -n[live]), 0.0)
            hit = found & (th < t)
            prim = np.where(hit, prim, -1)
        else:
            th, prim, hu, hv = _intersect(meshes, obj[live], pos[live], d[live], t)
            hit = prim >= 0
        t = np.where(hit, th, t)
        pos[live] += t[:, None] * d[live]
        T = np.exp(-st * t[:, None])
        pdf = _walk_pdf(st, t, hit)
        if bounce > 0:
            gpdf = _walk_pdf(fwd_stretch[:, None] * st, t, hit) * fwd_factor[:, None]
            if opp.any():
                bpdf = _walk_pdf(bwd_stretch[:, None] * st, t, hit) * bwd_factor[:, None]
                bf = back_frac[:, None]
                gpdf = np.where(opp[:, None], gpdf * (1.0 - bf) + bpdf * bf, gpdf)
            pdf = pdf * (1.0 - gf[:, None]) + gpdf * gf[:, None]
        tp[live] *= np.where(hit[:, None], T, ss * T) / np.einsum("ij,ij->i", cpdf, pdf)[:, None]
        if hit.any():
            r = live[hit]
            out_prim[r], out_u[r], out_v[r] = prim[hit], hu[hit], hv[hit]
            out_d[r] = d[r]
            done[r] = True
        keep = ~hit & (tp[live].max(axis=1) >= VOLUME_THROUGHPUT_EPSILON)
        live = live[keep]
    tp[~done] = 0.0
    return done, out_prim, out_u, out_v, out_d, tp


_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_TO_UNIT = 1.0 / 9007199254740992.0


@kernel
def _uniform(state):
    """(the next uniform number in [0, 1), the new state): splitmix64 on a uint64 counter."""
    s = state + _GOLDEN
    z = s
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    z = z ^ (z >> np.uint64(31))
    return np.float64(z >> np.uint64(11)) * _TO_UNIT, s


@kernel
def _around1(ax, ay, az, cos_t, phi):
    """The unit direction at angle acos(cos_t), azimuth phi about the unit axis a."""
    sign = 1.0 if az >= 0.0 else -1.0
    a = -1.0 / (sign + az)
    b = ax * ay * a
    tx, ty, tz = 1.0 + sign * ax * ax * a, sign * b, -sign * ax
    bx, by, bz = b, sign + ay * ay * a, -ay
    sin_t = math.sqrt(max(0.0, 1.0 - cos_t * cos_t))
    c, s = sin_t * math.cos(phi), sin_t * math.sin(phi)
    return (c * tx + s * bx + cos_t * ax, c * ty + s * by + cos_t * ay,
            c * tz + s * bz + cos_t * az)


@kernel
def _walk_pdf1(st, t, hit):
    T = math.exp(-st * t)
    return T if hit else st * T


@kernel
def walk_rows(fn, scene, starts, local_rows, idx, pos, d, n, p0, sigma_t, sigma_s,
              sigma_t_star, sigma_s_star, alpha, g, guided_org, v_len, phase_log, tp,
              seeds, out_prim, out_u, out_v, out_d, done, rays):
    """The walks idx (K,) int64 of walk()'s arrays stepped to their end, each through
    Embree from the kernel (accel._intersect_rows: rtcIntersect8 at address fn on the
    object's RTCScene at address scene, geometry starts, local triangle -> global row
    local_rows): walk()'s numpy steps one walk at a time, the same estimator (its random
    numbers from splitmix64 on the walk's seed, seeds (M,) uint64). Writes pos, d, tp and
    the out_* / done rows of the walks; rays (1,) int64 += the rays cast."""
    o1 = np.empty((1, 3))
    d1 = np.empty((1, 3))
    tm1 = np.empty(1)
    t1 = np.empty(1)
    p1 = np.empty(1, np.int64)
    u1 = np.empty(1)
    v1 = np.empty(1)
    st = np.empty(3)
    ss = np.empty(3)
    cp = np.empty(3)
    nray = 0
    for k in range(idx.shape[0]):
        i = idx[k]
        state = seeds[i]
        opp = False
        odist = 0.0
        nx, ny, nz = n[i, 0], n[i, 1], n[i, 2]
        v = v_len[i]
        plog = phase_log[i]
        for bounce in range(BSSRDF_MAX_BOUNCES):
            late = bounce > SIMILARITY_LEVEL
            for c in range(3):
                st[c] = sigma_t_star[i, c] if late else sigma_t[i, c]
                ss[c] = sigma_s_star[i, c] if late else sigma_s[i, c]
            tot = 0.0
            for c in range(3):
                cp[c] = tp[i, c] * alpha[i, c]
                tot += cp[c]
            for c in range(3):
                cp[c] = cp[c] / tot if tot > 0.0 else 1.0 / 3.0
            r0, state = _uniform(state)
            ch = 0 if r0 < cp[0] else (1 if r0 < cp[0] + cp[1] else 2)
            sample_st = st[ch]
            gf = 0.0
            back_frac = 0.0
            fwd_factor = bwd_factor = 0.0
            fwd_stretch = bwd_stretch = 1.0
            if bounce > 0:
                gl = 0.0 if late else g[i]
                gf = 0.75 if late else guided_org[i]
                r2, state = _uniform(state)
                guided = r2 < gf
                backward = False
                if opp:
                    x = -((pos[i, 0] - p0[i, 0]) * nx + (pos[i, 1] - p0[i, 1]) * ny
                          + (pos[i, 2] - p0[i, 2]) * nz)
                    x = min(max(x, 0.0), odist)
                    back_frac = 1.0 / (1.0 + math.exp((odist - 2.0 * x) / v))
                    r3, state = _uniform(state)
                    backward = r3 < back_frac
                r4, state = _uniform(state)
                r5, state = _uniform(state)
                ox, oy, oz = d[i, 0], d[i, 1], d[i, 2]
                if guided:
                    cos_t = v - (v + 1.0) * math.exp(-r4 * plog)
                    if backward:
                        cos_t = -cos_t
                    cos_t = min(max(cos_t, -1.0), 1.0)
                    dx, dy, dz = _around1(nx, ny, nz, cos_t, 2.0 * math.pi * r5)
                else:
                    if abs(gl) < 1e-3:
                        ch_t = 1.0 - 2.0 * r4
                    else:
                        kk = (1.0 - gl * gl) / (1.0 - gl + 2.0 * gl * r4)
                        ch_t = (1.0 + gl * gl - kk * kk) / (2.0 * gl)
                    ch_t = min(max(ch_t, -1.0), 1.0)
                    dx, dy, dz = _around1(ox, oy, oz, ch_t, 2.0 * math.pi * r5)
                    cos_t = dx * nx + dy * ny + dz * nz
                cd = ox * dx + oy * dy + oz * dz
                hg = (1.0 - gl * gl) / max(1.0 + gl * gl - 2.0 * gl * cd, 1e-300) ** 1.5 / (
                    4.0 * math.pi)
                fwd_factor = (0.5 / math.pi) / ((v - cos_t) * plog) / hg
                bwd_factor = (0.5 / math.pi) / ((v + cos_t) * plog) / hg
                fwd_stretch = 1.0 - cos_t / v
                bwd_stretch = 1.0 + cos_t / v
                if guided:
                    sample_st *= bwd_stretch if backward else fwd_stretch
                d[i, 0], d[i, 1], d[i, 2] = dx, dy, dz
            r1, state = _uniform(state)
            t = -math.log1p(-r1) / sample_st
            if bounce == 0:
                reach = max(t, 10.0 / min(st[0], min(st[1], st[2])))
            else:
                reach = t
            for c in range(3):
                o1[0, c] = pos[i, c]
                d1[0, c] = d[i, c]
            tm1[0] = reach
            _intersect_rows(fn, scene, o1, d1, tm1, starts, t1, p1, u1, v1)
            nray += 1
            found = p1[0] >= 0 and t1[0] <= reach
            if bounce == 0:
                opp = found
                if found:
                    odist = -((pos[i, 0] + t1[0] * d[i, 0] - p0[i, 0]) * nx
                              + (pos[i, 1] + t1[0] * d[i, 1] - p0[i, 1]) * ny
                              + (pos[i, 2] + t1[0] * d[i, 2] - p0[i, 2]) * nz)
                hit = found and t1[0] < t
            else:
                hit = found
            if hit:
                t = t1[0]
            for c in range(3):
                pos[i, c] += t * d[i, c]
            denom = 0.0
            for c in range(3):
                pdf = _walk_pdf1(st[c], t, hit)
                if bounce > 0:
                    gp = _walk_pdf1(fwd_stretch * st[c], t, hit) * fwd_factor
                    if opp:
                        bp = _walk_pdf1(bwd_stretch * st[c], t, hit) * bwd_factor
                        gp = gp * (1.0 - back_frac) + bp * back_frac
                    pdf = pdf * (1.0 - gf) + gp * gf
                denom += cp[c] * pdf
            mx = 0.0
            for c in range(3):
                T = math.exp(-st[c] * t)
                tp[i, c] *= (T if hit else ss[c] * T) / denom
                mx = max(mx, tp[i, c])
            if hit:
                out_prim[i] = local_rows[p1[0]]
                out_u[i], out_v[i] = u1[0], v1[0]
                for c in range(3):
                    out_d[i, c] = d[i, c]
                done[i] = True
                break
            if mx < VOLUME_THROUGHPUT_EPSILON:
                break
    rays[0] += nray


def _compiled_walk(meshes, obj, live):
    """Per object of the walks live: (rtcIntersect8's address, the object's RTCScene
    address, its geometry starts, its global rows, the walks' rows (K,) int64), or None
    where the trace kernel cannot be used (accel._kernel_hits_address 0, a BVH in
    blocks): the numpy steps then."""
    from . import accel as _accel
    if not len(live) or _accel._LIBRARY is None:
        return None
    fn = _accel._kernel_hits_address()
    if not fn:
        return None
    out = []
    o = np.take(obj, live)
    for ob in np.unique(o):
        acc, rows = meshes.get(int(ob))
        if len(acc._blocks) != 1:
            return None
        block = acc._blocks[0]
        out.append((fn, _accel._scene_address(block.scene), block.starts, rows,
                    np.ascontiguousarray(live[o == ob], np.int64)))
    return out


def _walk_pdf(sigma_t, t, hit):
    """Cycles' subsurface_random_walk_pdf per channel: T = exp(-sigma_t t), T where the
    ray reached the surface (hit), sigma_t T where it stopped inside."""
    T = np.exp(-sigma_t * t[:, None])
    return np.where(hit[:, None], T, sigma_t * T)


def _hg_pdf(cos_t, g):
    """Henyey-Greenstein's density (1/sr) at cos_t between the old and new directions."""
    return (1.0 - g * g) / np.maximum(1.0 + g * g - 2.0 * g * cos_t, 1e-300) ** 1.5 / (
        4.0 * math.pi)


def _intersect(meshes, obj, o, d, tmax):
    """Closest hits within tmax against each walk's own object: (t, global prim (-1:
    none), u, v)."""
    k = len(o)
    t, prim = np.full(k, np.inf), np.full(k, -1, np.int64)
    u, v = np.zeros(k), np.zeros(k)
    for ob in np.unique(obj):
        sel = np.flatnonzero(obj == ob) if len(obj) and (obj != ob).any() else slice(None)
        accel, rows = meshes.get(int(ob))
        tt, pp, uu, vv = accel.intersect(o[sel], d[sel], tmax[sel])
        hit = (pp >= 0) & (tt <= tmax[sel])
        t[sel] = np.where(hit, tt, np.inf)
        prim[sel] = np.where(hit, rows[np.maximum(pp, 0)], -1)
        u[sel], v[sel] = uu, vv
    return t, prim, u, v


class SubsurfaceWalks:
    """The camera paths' subsurface hook for one render context: which material rows walk
    (MaterialTable.subsurface), the objects' BVHs, and the two steps the camera bounce
    takes (entries: split a shaded row's diffuse weight; exits: walk and build the exit
    hits)."""

    def __init__(self, ctx, params: list):
        self.ctx = ctx
        self.params = params  # per material row: SubsurfaceParams or None
        self.walking = np.array([p is not None for p in params], np.bool_)
        self.meshes = ObjectMeshes(ctx.geo)
        # Counts for bench/ (walks started, walks that left the surface, rays cast).
        self.stats = {"walks": 0, "exits": 0, "rays": 0}
        self._stats_lock = threading.Lock()

    @classmethod
    def for_context(cls, ctx):
        """The hook, or None where nothing walks (the setting off, or no material with a
        subsurface closure): the camera paths are then untouched."""
        cached = getattr(ctx, "_subsurface_walks", False)
        if cached is not False:
            return cached
        params = getattr(ctx.table, "subsurface", None) or []
        hook = None
        # (Instanced rows stored once per prototype, engine/sharedrows.py: the objects'
        # own BVHs are not built from them yet; such scenes keep the stand-in.)
        if (getattr(ctx.settings, "subsurface_walk", True)
                and any(p is not None for p in params)
                and getattr(ctx.geo, "shared", None) is None):
            hook = cls(ctx, list(params))
        ctx._subsurface_walks = hook
        return hook

    def entries(self, hit, rows, wd):
        """For the shaded rows `rows` (K,) of the bounce's hits (None: all) with diffuse
        weights wd (K,3): scales wd in place to the diffuse closure's share (1 - w) c / b
        of the stand-in colour b the table gives (per hit for a textured colour or
        weight), and returns (j (J,) the positions in rows that walk, W (J,3) the walks'
        starting weight w wd / b, per_walk: (albedo (J,3) their Base Colors c, radius
        (J,3) their Radius x Scale), or None where every walk's are its material's
        constants), or None."""
        mat = hit.mat if rows is None else np.take(hit.mat, rows)
        walking = np.take(self.walking, mat)
        if not walking.any():
            return None
        j = np.flatnonzero(walking)
        base = hit.base if rows is None else np.take(hit.base, rows, axis=0)
        b = base[j]
        sp = [self.params[i] for i in mat[j]]
        c = np.array([s.color for s in sp], np.float64).reshape(-1, 3)
        w = np.array([s.weight for s in sp], np.float64)[:, None]
        radius = np.array([s.radius for s in sp], np.float64).reshape(-1, 3)
        textured = self._textured(hit, rows, j, mat[j], c, w, radius)
        layer = np.divide(wd[j], b, out=np.zeros_like(b), where=b > 0)
        small = radius < BSSRDF_MIN_RADIUS
        # Channels too thin to walk stay a diffuse closure of the BSSRDF's weight (w c).
        wd[j] = layer * ((1.0 - w) * c + np.where(small, w * c, 0.0))
        W = np.where(small, 0.0, layer * w)
        keep = W.max(axis=1) > 0
        return j[keep], W[keep], ((c[keep], radius[keep]) if textured else None)

    def _textured(self, hit, rows, j, mat, c, w, radius) -> bool:
        """Overwrites c (J,3), w (J,1), radius (J,3) in place with the per-hit colour,
        weight and radius of the walks whose material has textured ones (SubsurfaceParams.per_hit, evaluated at
        the entry as engine/bsdf.surface_hit evaluates the surface's textures); whether
        there were any."""
        mats = [int(mi) for mi in np.unique(mat) if self.params[mi].textured]
        if not mats:
            return False
        from .shadernodes import ShadingGeometry
        r = j if rows is None else np.asarray(rows)[j]
        ns = hit.ns if hit.n_smooth is None else hit.n_smooth
        for mi in mats:
            k = np.flatnonzero(mat == mi)
            rk = r[k]
            sg = ShadingGeometry(self.ctx.geo, np.take(ns, rk, axis=0),
                                 np.take(hit.wo, rk, axis=0), ~np.take(hit.front, rk))
            bary = np.take(hit.bary, rk, axis=0)
            ck, wk, rk = self.params[mi].per_hit(sg, np.take(hit.prim, rk), bary[:, 0],
                                                 bary[:, 1])
            c[k] = ck
            w[k, 0] = wk
            radius[k] = rk
        return True

    def exits(self, hit, rows, j, W, rng, per_walk=None):
        """Walk from the rows rows[j] (rows None: j are the hits' rows) of the bounce's
        hits with starting weights W (J,3) (per_walk: entries' (albedo, radius) of each
        walk, None: the materials'). Returns (i (E,) the positions in j whose walk left the surface,
        the exit SurfaceHit (E rows, seen from outside), wd (E,3) the exit's Lambertian
        weight W x the walk's throughput)."""
        from .bsdf import surface_hit
        r = j if rows is None else np.asarray(rows)[j]
        ctx = self.ctx
        prim = np.take(hit.prim, r)
        obj = np.take(np.asarray(ctx.geo.object_id), prim)
        sp = [self.params[i] for i in np.take(hit.mat, r)]
        offset = (np.take(hit.offset, r) if hit.offset is not None
                  else np.full(len(r), 1e-6 * max(ctx.geo.extent, 1e-3)))
        counts = {}
        ns, ng, wo = (np.ascontiguousarray(np.take(a, r, axis=0), np.float64)
                      for a in (hit.ns, hit.ng, hit.wo))
        n_entry = None
        if BSSRDF_NORMALS:
            n_entry = np.empty_like(ns)
            bssrdf_normals(ns, ng, wo, n_entry)
        ok, xprim, xu, xv, xd, tp = walk(
            self.meshes, obj, np.take(hit.p, r, axis=0), ns, ng, wo, offset, sp, rng, counts,
            *(per_walk or (None, None)), n_entry=n_entry)
        i = np.flatnonzero(ok & (tp.max(axis=1) > 0))
        with self._stats_lock:
            self.stats["walks"] += len(r)
            self.stats["exits"] += len(i)
            self.stats["rays"] += counts.get("rays", 0)
        if not len(i):
            return None
        # Seen from outside (Cycles turns the exit ray round: front-facing normals).
        xhit = surface_hit(ctx.geo, ctx.table, xprim[i], xu[i], xv[i], -xd[i],
                           unguarded=self._exit_unguarded(xprim[i], xu[i], xv[i]))
        return i, xhit, W[i] * tp[i]

    def _exit_unguarded(self, prim, u, v):
        """(E,) bool: the exits whose interpolated shading normal the Lambertian keeps
        where the walk's direction leaves below it (bsdf.surface_hit's unguarded rows;
        Cycles' subsurface_shader_data_setup takes sd->N as it is), every exit but those
        whose normal points into the surface (ns . ng <= 0: broken custom normals keep
        the guard's fall-back to the face, as turnedglossy's rows); None: the guard
        everywhere (BSSRDF_NORMALS off, or no interpolated normals)."""
        geo = self.ctx.geo
        cn = getattr(geo, "corner_normals", None)
        if not BSSRDF_NORMALS or cn is None or not len(cn):
            return None
        ns = geo.shading_normals(prim, u, v)
        return np.einsum("ij,ij->i", ns, np.asarray(geo.ng[prim], np.float64)) > 0.0


def material_params(materials) -> list:
    """Per material row: its SubsurfaceParams (Material.subsurface) or None."""
    return [getattr(m, "subsurface", None) for m in materials]


@register_warm_up
def _warm_up():
    """Compile (or load) walk_rows and bssrdf_normals (no walk: nothing is traced)."""
    e3, e1 = np.zeros((0, 3)), np.zeros(0)
    bssrdf_normals(e3, e3, e3, np.zeros((0, 3)))
    none = np.zeros(0, np.int64)
    walk_rows(0, 0, np.zeros(1, np.int64), none, none, e3, e3, e3, e3, e3, e3, e3, e3, e3,
              e1, e1, e1, e1, e3, np.zeros(0, np.uint64), none.copy(), e1, e1, e3,
              np.zeros(0, np.bool_), np.zeros(1, np.int64))
