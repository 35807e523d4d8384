"""Surface scattering: the lobes of our Principled-like material, Fresnel, sampling.

At a hit the material splits into lobes with RGB weights that sum to at most 1:
  diffuse (Lambert, base colour)        -> photon storage / radiance estimate
  metal, glass reflect, glass transmit, coat reflect, pass-through (alpha)
                                        -> specular continuation (perfect or rough)
The camera pass evaluates the diffuse lobe at the hit and continues one specular lobe;
the photon pass picks one lobe by Russian roulette (absorb with what is left).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import Geometry, MaterialTable
from .rayoffset import offset_along_normal
from .sampling import dot, normalize, reflect, to_world
from .textures import material_alpha

SPEC_LOBES = ("pass", "metal", "glass_r", "glass_t", "coat")


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
    p = geo.hit_points(prim, u, v)
    ng = np.take(geo.ng, prim, axis=0)
    front = dot(d, ng) < 0.0
    sign = np.where(front, 1.0, -1.0)[:, None]
    ng = ng * sign
    ns = geo.shading_normals(prim, u, v)
    mat = np.take(geo.material, prim)
    for mi, nmap in enumerate(table.normal_maps or ()):
        if nmap is None:
            continue
        sel = np.nonzero(mat == mi)[0]
        if len(sel):
            ns[sel] = nmap.perturb(geo, prim[sel], u[sel], v[sel], ns[sel])
    ns = ns * sign
    wo = -d
    # Shading normals that put the viewer below the surface would make black rings:
    # fall back to the geometric normal there (Veach's guard, simplified).
    bad = dot(ns, wo) <= 1e-6
    if bad.any():
        ns[bad] = ng[bad]
    base = np.take(table.base_color, mat, axis=0)
    for mi, tex in enumerate(table.textures):
        if tex is None:
            continue
        sel = np.nonzero(mat == mi)[0]
        if len(sel):
            # Clipped to [0, 1]: an albedo above 1 would create energy (HDR texels).
            rgb = tex.evaluate(geo, prim[sel], u[sel], v[sel])
            if rgb.ndim == 1:  # a value (factor) into a colour: grey
                rgb = rgb[:, None]
            base[sel] = base[sel] * np.clip(rgb, 0.0, 1.0)
    alpha = None
    if table.alpha_textures and any(t is not None for t in table.alpha_textures):
        alpha = material_alpha(table, geo, mat, prim, u, v)
    return SurfaceHit(p=p, ng=ng, ns=ns, wo=wo, front=front, mat=mat, base=base, prim=prim,
                      offset=geo.origin_offset(prim, u, v, p, ng),
                      bary=np.stack([u, v], axis=1), alpha=alpha)


def lobe_weights(table: MaterialTable, hit: SurfaceHit) -> dict[str, np.ndarray]:
    """RGB weight of each lobe for the incoming direction (sums to <= 1 per channel).

    Fresnel terms are evaluated only on rows whose material has a glass or coat lobe:
    elsewhere they are multiplied by an exact 0 (1 - 0*f = 1), so the result is bitwise
    the same as evaluating them everywhere."""
    m = hit.mat
    n = len(m)
    a1 = np.take(table.alpha, m) if hit.alpha is None else hit.alpha
    metal1 = np.take(table.metallic, m)
    trans1 = np.take(table.transmission, m)
    spec1 = np.take(table.specular, m)
    a, metal, trans, spec = a1[:, None], metal1[:, None], trans1[:, None], spec1[:, None]
    cos_i = np.clip(dot(hit.ns, hit.wo), 0.0, 1.0)
    f_glass1 = np.zeros(n)
    f_coat1 = np.zeros(n)
    gl = np.nonzero(trans1 != 0)[0]
    if len(gl):
        ior = np.take(table.ior, m[gl])
        f_glass1[gl] = fresnel_dielectric(cos_i[gl], np.where(hit.front[gl], ior, 1.0 / ior))
    ct = np.nonzero(spec1 != 0)[0]
    if len(ct):
        f_coat1[ct] = fresnel_dielectric(cos_i[ct], np.take(table.ior, m[ct]))
    f_glass, f_coat = f_glass1[:, None], f_coat1[:, None]
    base = hit.base
    not_metal = 1.0 - metal
    dielectric = a * not_metal * (1.0 - trans)
    ones = np.ones_like(base)
    if np.any(metal1 != 0):
        c5 = (1.0 - cos_i) ** 5
        schlick = base + (1.0 - base) * c5[:, None]
        metal_w = a * metal * schlick
    else:
        metal_w = np.zeros_like(base)  # a * 0 * schlick: schlick is finite (base in [0,1])
    glass = a * not_metal * trans
    return {
        "diffuse": dielectric * (1.0 - spec * f_coat) * base,
        "pass": (1.0 - a) * ones,
        "metal": metal_w,
        "glass_r": glass * f_glass * ones,
        "glass_t": glass * (1.0 - f_glass) * base,
        "coat": dielectric * spec * f_coat * ones,
    }


def _microfacet_normal(ns: np.ndarray, roughness: np.ndarray, rng: np.random.Generator):
    """Microfacet normal (alpha = roughness^2) around ns; exactly ns where roughness is 0.

    Sampled from Beckmann's distribution rather than GGX (Cycles' choice): GGX's long
    tail sends a few percent of even a near-mirror's rays 10 degrees or more off, and
    without light sampling for glossy lobes those that find a small bright light become
    fireflies (measured on the Figure 7 floor). Beckmann's tail falls off like a
    Gaussian: the highlight keeps its width, the faint halo around it is lost."""
    alpha = roughness * roughness
    rough = alpha > 1e-4
    if not rough.any():
        return ns
    m = ns.copy()
    idx = np.nonzero(rough)[0]
    u1 = rng.random(len(idx)); u2 = rng.random(len(idx))
    tan2 = -(alpha[idx] ** 2) * np.log1p(-u1)
    cos_t = 1.0 / np.sqrt(1.0 + tan2)
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    phi = 2.0 * np.pi * u2
    local = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)
    m[idx] = to_world(local, ns[idx])
    return m


def sample_specular(table: MaterialTable, hit: SurfaceHit, lobe: np.ndarray,
                    rng: np.random.Generator):
    """New directions for the chosen specular lobe index (into SPEC_LOBES).
    Returns (direction, valid, transmitted). Invalid = the sampled direction went to the
    wrong side of the surface (rough lobes): that energy is absorbed."""
    n = len(lobe)
    d_in = -hit.wo
    rough = table.roughness[hit.mat]
    m = _microfacet_normal(hit.ns, np.where(lobe == 0, 0.0, rough), rng)
    # Microfacet normals must face the viewer.
    flip = dot(m, hit.wo) < 0
    m[flip] = hit.ns[flip]
    out = reflect(d_in, m)
    transmitted = np.zeros(n, bool)
    passing = lobe == 0
    out[passing] = d_in[passing]
    transmitted |= passing
    refr = lobe == 3
    if refr.any():
        ior = table.ior[hit.mat[refr]]
        eta_ratio = np.where(hit.front[refr], 1.0 / ior, ior)
        t_dir, tir = refract(d_in[refr], m[refr], eta_ratio)
        r_dir = out[refr]
        out[refr] = np.where(tir[:, None], r_dir, t_dir)
        transmitted[np.nonzero(refr)[0][~tir]] = True
    side = dot(out, hit.ng)
    valid = np.where(transmitted, side < 0, side > 0) & np.isfinite(out).all(axis=1)
    return normalize(out), valid, transmitted
