"""Surface scattering: hits, their lobes (Cycles' Principled v2 closures), sampling.

At a hit the material splits into lobes (engine/closures/principled.py), each with an RGB
weight (its estimated albedo for the view direction):
  diffuse (Lambert under the layers above)      -> photon storage / radiance estimate
  pass (alpha), metal, glass reflect / transmit, dielectric specular, coat (GGX), sheen
                                                -> continuation by sampling the lobe
The camera pass evaluates the diffuse lobe at the hit (and the rough lobes' response to
lights, engine/integrator.py) and continues one other lobe; the photon pass picks one lobe
by Russian roulette (absorb with what is left).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camerakernels import face_shading_normals, hit_geometry
from .closures import principled as pr
from .geometry import Geometry, MaterialTable
from .rayoffset import offset_along_normal
from .sampling import dot, max3, normalize
from .shadernodes import ShadingGeometry
from .textures import hit_emission, material_alpha, rows_by_material, scalar_params

# Lobe names in engine/closures/principled.py's order (its L_* indices).
LOBE_NAMES = ("diffuse", "pass", "metal", "glass_r", "glass_t", "spec", "coat", "sheen")
SPEC_LOBES = LOBE_NAMES[1:]  # the lobes a path continues through
# glass_r and glass_t are one lobe when sampled (sample_specular): chosen with their
# summed probability, then reflected or refracted.
GLASS_R, GLASS_T = SPEC_LOBES.index("glass_r"), SPEC_LOBES.index("glass_t")


def fresnel_dielectric(cos_i: np.ndarray, eta: np.ndarray) -> np.ndarray:
    """Unpolarised Fresnel reflectance; eta = n_transmitted / n_incident; 1 under TIR."""
    cos_i = np.clip(cos_i, 0.0, 1.0)
    eta = np.maximum(eta, 1e-6)
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    rs = (cos_i - eta * cos_t) / np.maximum(cos_i + eta * cos_t, 1e-300)
    rp = (eta * cos_i - cos_t) / np.maximum(eta * cos_i + cos_t, 1e-300)
    f = 0.5 * (rs * rs + rp * rp)
    return np.where(sin2_t >= 1.0, 1.0, np.clip(f, 0.0, 1.0))


def refract(d: np.ndarray, n: np.ndarray, eta_ratio: np.ndarray):
    """Refract unit d through a surface with unit normal n facing against d.
    eta_ratio = n_incident / n_transmitted. Returns (direction, total_internal_reflection)."""
    cos_i = -dot(d, n)
    sin2_t = eta_ratio * eta_ratio * np.maximum(0.0, 1.0 - cos_i * cos_i)
    tir = sin2_t >= 1.0
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    t = eta_ratio[:, None] * d + (eta_ratio * cos_i - cos_t)[:, None] * n
    return normalize(t), tir


@dataclass
class SurfaceHit:
    """Everything the integrators need to know about a batch of ray hits."""

    p: np.ndarray         # (N,3) position
    ng: np.ndarray        # geometric normal facing the incoming ray
    ns: np.ndarray        # shading normal on the same side
    wo: np.ndarray        # direction back towards the ray origin
    front: np.ndarray     # ray arrived on the side the winding order calls outside
    mat: np.ndarray       # material index
    base: np.ndarray      # (N,3) base colour (texture applied)
    prim: np.ndarray
    offset: np.ndarray | None = None  # (N,) distance along ng that takes a ray origin
                          # clear of p's triangle (a rounding-error bound, engine/rayoffset.py)
    bary: np.ndarray | None = None    # (N,2) barycentric weights of corners 1 and 2
    alpha: np.ndarray | None = None   # (N,) per-hit alpha where a material has an alpha
                          # texture (textures.material_alpha); None: the materials' constants
    prm: np.ndarray | None = None     # (N, principled.N_PACK) lobes (bsdf.closures)
    lobe_albedo: np.ndarray | None = None  # (N, len(LOBE_NAMES), 3)
    n_smooth: np.ndarray | None = None  # (N,3) the smooth shading normal before Normal Map /
                          # Bump nodes, on ns's side, where one bent ns (else ns itself);
                          # None: no bent normal in the batch (normalmap.bump_shadowing)
    params: np.ndarray | None = None  # (N, principled.N_MAT) closure parameters per hit
                          # where a material has texture-driven scalar inputs
                          # (textures.scalar_params); None: the materials' rows
    emission: np.ndarray | None = None  # (N,3) emitted radiance (emission textures applied)

    def clear(self, rows, d) -> np.ndarray:
        """Origins for rays leaving hits[rows] in directions d: p moved off its triangle
        along ng by `offset`, to the side d leaves (pbrt-v4's OffsetRayOrigin)."""
        return offset_along_normal(self.p[rows], self.ng[rows], d, self.offset[rows])

    def take(self, idx) -> "SurfaceHit":
        """The hits at rows idx (np.take(axis=0) is ~4x faster than fancy indexing)."""
        return SurfaceHit(*(None if getattr(self, k) is None else
                            np.take(getattr(self, k), idx, axis=0)
                            for k in self.__dataclass_fields__))


def surface_hit(geo: Geometry, table: MaterialTable, prim, u, v, d) -> SurfaceHit:
    """Surface data at N ray hits: triangles prim (N,), barycentrics u, v (N,) of corners
    1 and 2, ray directions d (N,3). Positions, normals, material, base colour and the
    ray-origin offset come from one compiled pass (camerakernels.hit_geometry); normal
    maps, colour textures and alpha textures are applied after it, per material."""
    n = len(prim)
    u = np.ascontiguousarray(u, dtype=np.float64)
    v = np.ascontiguousarray(v, dtype=np.float64)
    d = np.ascontiguousarray(d, dtype=np.float64)
    p, ng, ns, base = (np.empty((n, 3)) for _ in range(4))
    front = np.empty(n, np.bool_)
    mat = np.empty(n, geo.material.dtype)  # as np.take(geo.material, prim) gave
    offset = np.empty(n)
    rows, tabs = geo.hit_tables(prim, "v0", "e1", "e2", "corner_normals", "material")
    hit_geometry(rows, u, v, d, *tabs, table.base_color, p, ng, ns, front, mat, base, offset)
    floor = geo.instance_offset_floor(prim, p, ng)  # shared instances: object-space rounding
    if floor is not None:
        np.maximum(offset, floor, out=offset)
    n_smooth = bent = None
    for _, nmap, sel in rows_by_material(table.normal_maps, mat):
        if n_smooth is None:
            n_smooth, bent = ns.copy(), np.zeros(len(ns), bool)
        ns[sel] = nmap.perturb(geo, prim[sel], u[sel], v[sel], ns[sel])
        bent[sel] = True
    # Shading normals turned to the ray's side; the geometric normal where they would put
    # the viewer below the surface, except normals a Normal Map / Bump node bent: Cycles
    # keeps those (its bump shadowing term, engine/normalmap.py, handles the light side).
    face_shading_normals(ns, ng, front, d, bent if bent is not None else np.zeros(n, np.bool_))
    if bent is not None:
        sign = np.where(front, 1.0, -1.0)[:, None]
        n_smooth = np.where(bent[:, None], n_smooth * sign, ns)
    wo = -d
    # What view-dependent nodes (Layer Weight, Fresnel) read: Cycles' sd->N (the smooth
    # normal on the ray's side) and sd->wi, row for row with prim.
    sg = ShadingGeometry(geo, ns if n_smooth is None else n_smooth, wo, ~front)
    for _, tex, sel in rows_by_material(table.textures, mat):
        # Not clipped above 1, as Cycles (max(colour, 0)): the diffuse lobe takes an
        # albedo above 1, the metal / glass lobes clip it themselves
        # (closures/principled.py); photons carry it in their power (Russian
        # roulette probabilities stay <= 1, engine/photons.py).
        rgb = tex.evaluate(sg.rows(sel), prim[sel], u[sel], v[sel])
        if rgb.ndim == 1:  # a value (factor) into a colour: grey
            rgb = rgb[:, None]
        base[sel] = base[sel] * np.maximum(rgb, 0.0)
    alpha = None
    if table.alpha_textures and any(t is not None for t in table.alpha_textures):
        alpha = material_alpha(table, sg, mat, prim, u, v)
    return SurfaceHit(p=p, ng=ng, ns=ns, wo=wo, front=front, mat=mat, base=base, prim=prim,
                      offset=offset, bary=np.stack([u, v], axis=1), alpha=alpha,
                      n_smooth=n_smooth, params=scalar_params(table, sg, mat, prim, u, v),
                      emission=hit_emission(table, sg, mat, prim, u, v))


def closures(table: MaterialTable, hit: SurfaceHit):
    """The hits' lobes as engine/closures/principled.py builds them (Cycles' Principled v2
    layering): (packed per-hit parameters (N, principled.N_PACK), estimated albedo of each
    lobe (N, len(LOBE_NAMES), 3)). Cached on the hit."""
    if hit.prm is None or hit.lobe_albedo is None:
        cos_o = np.einsum("ij,ij->i", hit.ns, hit.wo)
        # Glossy lobes on a normal that keeps their mirror direction above the surface
        # (Cycles' ensure_valid_specular_reflection), where ns differs from ng; the lobes
        # are set up with the view cosine about that normal.
        local = np.zeros((len(cos_o), 3))
        pr.glossy_normals(np.ascontiguousarray(hit.ns, np.float64),
                          np.ascontiguousarray(hit.ng, np.float64),
                          np.ascontiguousarray(hit.wo, np.float64), local, cos_o)
        if hit.params is None:
            params, rows = table.closure_params, hit.mat
        else:  # texture-driven scalar inputs: one parameter row per hit
            params, rows = hit.params, np.arange(len(hit.mat))
        # Not yet for glass (docs/textures.md): its hits keep the shading normal.
        glass = np.nonzero(np.take(params[:, pr.M_TRANS], rows) > 0)[0]
        if len(glass):
            local[glass] = 0.0
            cos_o[glass] = np.einsum("ij,ij->i", hit.ns[glass], hit.wo[glass])
        hit.prm, hit.lobe_albedo = pr.setup_np(params, rows, hit.base, cos_o, hit.front,
                                               _hit_alpha(table, hit))
        hit.prm[:, pr.P_GN:pr.P_GN + 3] = local
    return hit.prm, hit.lobe_albedo


def _hit_alpha(table: MaterialTable, hit: SurfaceHit) -> np.ndarray:
    """(N,) alpha at the hits: a per-hit value where the hit carries one (alpha
    textures), else the materials' constants."""
    per_hit = getattr(hit, "alpha", None)
    return np.take(table.alpha, hit.mat) if per_hit is None else per_hit


def lobe_weights(table: MaterialTable, hit: SurfaceHit) -> dict[str, np.ndarray]:
    """RGB weight (estimated albedo for the view direction) of each lobe, by name
    (LOBE_NAMES). The diffuse weight is exact (Lambert under the layers above); the others
    are Cycles' albedo estimates and serve as lobe-choice probabilities: the sampled
    direction's own weight (sample_specular) makes the estimate unbiased."""
    _, alb = closures(table, hit)
    return {name: alb[:, i] for i, name in enumerate(LOBE_NAMES)}


def sample_specular(table: MaterialTable, hit: SurfaceHit, lobe: np.ndarray,
                    rng: np.random.Generator):
    """New directions for the chosen lobe index (into SPEC_LOBES), GGX visible-normal
    sampling (mirror-like below ggx.ALPHA_MIN); glass_r and glass_t both sample the whole
    glass lobe (reflect or refract: `transmitted` says which). Returns (direction, valid,
    transmitted, weight (N,3) = f cos / pdf of that lobe). Invalid = no direction (the
    sample left through the wrong side of the surface): that energy is absorbed."""
    n = len(lobe)
    prm, _ = closures(table, hit)
    d_in = -hit.wo
    out = np.empty((n, 3))
    weight = np.zeros((n, 3))
    transmitted = np.zeros(n, bool)
    passing = lobe == 0
    if passing.any():
        out[passing] = d_in[passing]
        transmitted[passing] = True
        a = _hit_alpha(table, hit)[passing]
        # The pass lobe's weight: (1 - alpha) x the Transparent BSDF's colour.
        tint = table.closure_params[hit.mat[passing], pr.M_TTINT:pr.M_TTINT + 3]
        weight[passing] = (1.0 - a)[:, None] * tint
    rows = np.nonzero(~passing)[0]
    if len(rows):
        u1, u2, u3 = rng.random(len(rows)), rng.random(len(rows)), rng.random(len(rows))
        d = np.empty((len(rows), 3))
        w = np.empty((len(rows), 3))
        tr = np.empty(len(rows), np.bool_)
        pr.sample_lobes(np.ascontiguousarray(prm[rows]),
                        (lobe[rows] + 1).astype(np.int64),  # SPEC_LOBES -> LOBE_NAMES
                        np.ascontiguousarray(hit.ns[rows], np.float64),
                        np.ascontiguousarray(hit.wo[rows], np.float64), u1, u2, u3, d, w, tr)
        out[rows], weight[rows], transmitted[rows] = d, w, tr
    side = dot(out, hit.ng)
    valid = (np.where(transmitted, side < 0, side > 0) & np.isfinite(out).all(axis=1)
             & (max3(weight) > 0))
    return out, valid, transmitted, weight
