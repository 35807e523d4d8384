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

from .anisotropy import set_hit_tangents
from .bump import Bump
from .camerakernels import face_shading_normals, hit_closures, hit_geometry, surface_lobes
from .filterglossy import NO_BLUR
from .closures import principled as pr
from . import raymaterials
from .displacement import DisplacedNormals
from .geometry import Geometry, MaterialTable
from .rayoffset import offset_along_normal
from .sampling import dot, max3, normalize
from .shadernodes import ShadingGeometry
from .textures import hit_emission, material_alpha, rows_by_material, scalar_params

# Lobe names in engine/closures/principled.py's order (its L_* indices).
LOBE_NAMES = ("diffuse", "pass", "metal", "glass_r", "glass_t", "spec", "coat", "sheen",
              "translucent")
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
    prm: np.ndarray | None = None     # (N, principled.N_PACK) lobes (bsdf.closures; on a
                          # camera bounce's hits camerakernels.shade_lobes's, whose
                          # diffuse-only rows are set only when the direct stage reads them)
    lobe_albedo: np.ndarray | None = None  # (N, len(LOBE_NAMES), 3)
    n_smooth: np.ndarray | None = None  # (N,3) the smooth shading normal before Normal Map /
                          # Bump nodes, on ns's side, where one bent ns (else ns itself);
                          # None: no bent normal in the batch (normalmap.bump_shadowing)
    params: np.ndarray | None = None  # (N, principled.N_MAT) closure parameters per hit
                          # where a material has texture-driven scalar inputs
                          # (textures.scalar_params); None: the materials' rows
    emission: np.ndarray | None = None  # (N,3) emitted radiance (emission textures applied;
                          # a read-only zero-stride view of zeros when no material emits)
    medium: np.ndarray | None = None  # (N,) int64 the medium the hit point is in (a material
                          # row, -1: none known; engine/media.py), set by the camera paths:
                          # shadow and gather rays from it start in that medium
    min_ray_pdf: np.ndarray | None = None  # (N,) 1/sr the camera path's min_ray_pdf before
                          # this hit (Cycles' Filter Glossy, engine/filterglossy.PathBlur),
                          # set by the camera paths: the split's pdf at D is at most it
                          # (glossysplit.DiffusePdf: the maps' per-photon test and the
                          # gather chains' start); None: inf (a camera ray's first hit)
    footprint: np.ndarray | None = None  # (N,) m the path's ray footprint at this hit
                          # (Cycles' compact sd->dP), set by the camera paths and the
                          # gather rays from them: the gather rays' ends take it on
                          # (bump.transfer_footprint); None: not known (their ends take
                          # the geometry's view_footprint)
    spread: np.ndarray | None = None  # (N,) rad the path's compact ray dD (the camera's:
                          # Cycles 4.2-5.1 keep it through every bounce; orthographic 0)

    def clear(self, rows, d) -> np.ndarray:
        """Origins for rays leaving hits[rows] in directions d: p moved off its triangle
        along ng by `offset`, to the side d leaves (pbrt-v4's OffsetRayOrigin)."""
        return offset_along_normal(self.p[rows], self.ng[rows], d, self.offset[rows])

    def take(self, idx) -> "SurfaceHit":
        """The hits at rows idx (N,) int: a HitRows view whose fields are copied from this
        batch (np.take(axis=0)) only when first read, so a subset handed to a stage that
        reads five fields does not copy the other ones (the packed lobes and their albedos
        alone are ~530 of a hit's ~720 bytes)."""
        return HitRows(self, idx)


def _row_field(name):
    """HitRows' property for field `name`: the source's rows, taken on first read;
    assigned values (closures' cache) replace it."""
    def get(self):
        cache = self.__dict__
        if name not in cache:
            a = getattr(self._source, name)
            cache[name] = None if a is None else np.take(a, self._rows, axis=0)
        return cache[name]

    def put(self, value):
        self.__dict__[name] = value

    return property(get, put)


class HitRows(SurfaceHit):
    """Rows `rows` of a SurfaceHit (SurfaceHit.take): each field is that field's rows of
    the source, copied when first read (then kept); a field assigned here (e.g. the lobes
    bsdf.closures computes) is this view's own. Behaves as the SurfaceHit take copied."""

    def __init__(self, source: SurfaceHit, rows):
        self.__dict__["_source"] = source
        self.__dict__["_rows"] = rows


for _name in SurfaceHit.__dataclass_fields__:
    setattr(HitRows, _name, _row_field(_name))
del _name


def _as_float64(*arrays):
    """The hit kernels' inputs as C-contiguous float64 (no copy when they already are)."""
    return tuple(np.ascontiguousarray(a, dtype=np.float64) for a in arrays)


def _hit_outputs(geo: Geometry, n: int):
    """hit_geometry's outputs for n hits: p, ng, ns, base (n,3), front (n,) bool, mat (n,)
    of geo.material's dtype (as np.take(geo.material, prim) gave), offset (n,), bary (n,2)."""
    p, ng, ns, base = (np.empty((n, 3)) for _ in range(4))
    return (p, ng, ns, base, np.empty(n, np.bool_), np.empty(n, geo.material.dtype),
            np.empty(n), np.empty((n, 2)))


def _offset_floor(geo: Geometry, prim, p, ng, offset):
    """Raise the ray-origin offsets (N,) in place to the shared instances' object-space
    rounding floor (Geometry.instance_offset_floor), where there is one."""
    floor = geo.instance_offset_floor(prim, p, ng)
    if floor is not None:
        np.maximum(offset, floor, out=offset)


def surface_hit(geo: Geometry, table: MaterialTable, prim, u, v, d,
                material=None, unguarded=None, footprint=None) -> SurfaceHit:
    """Surface data at N ray hits: triangles prim (N,), barycentrics u, v (N,) of corners
    1 and 2, ray directions d (N,3). Positions, normals, material, base colour and the
    ray-origin offset come from one compiled pass (camerakernels.hit_geometry); normal
    maps, colour textures and alpha textures are applied after it, per material.
    material (N,): each hit's material row where it is not its triangle's (the ray
    class's Light Path variant: engine/raymaterials.path_materials); None: the triangles'.
    unguarded (N,) bool: rows whose shading normal is kept where it puts the viewer below
    the surface (no guard; engine/turnedlight.py: smooth glass Cycles turns); None: none.
    footprint (N,) m: each ray's footprint at its hit (Cycles' compact sd->dP), which Bump
    nodes take their differences over; None: the geometry's view_footprint
    (engine/bump.py)."""
    n = len(prim)
    u, v, d = _as_float64(u, v, d)
    p, ng, ns, base, front, mat, offset, bary = _hit_outputs(geo, n)
    rows, tabs = raymaterials.hit_tables(geo, prim, material, "v0", "e1", "e2",
                                         "corner_normals", "material")
    hit_geometry(rows, u, v, d, *tabs, table.base_color, p, ng, ns, front, mat, base, offset,
                 bary)
    _offset_floor(geo, prim, p, ng, offset)
    n_smooth = bent = None
    for _, nmap, sel in rows_by_material(table.normal_maps, mat):
        if n_smooth is None:
            n_smooth, bent = ns.copy(), np.zeros(len(ns), bool)
        if isinstance(nmap, DisplacedNormals):
            # The displacement's bump sets Cycles' sd->N itself: the smooth normal the
            # view-dependent nodes and the bump shadowing term read.
            # Kept where the viewer is below it, as a bumped normal (bent).
            ns[sel] = _perturb(nmap.bump, geo, prim, u, v, ns, sel, footprint)
            n_smooth[sel] = ns[sel]
            bent[sel] = True
            nmap = nmap.then
            if nmap is None:
                continue
        ns[sel] = _perturb(nmap, geo, prim, u, v, ns, sel, footprint)
        bent[sel] = True
    # Shading normals turned to the ray's side; the geometric normal where they would put
    # the viewer below the surface, except normals a Normal Map / Bump node bent: Cycles
    # keeps those (its bump shadowing term, engine/normalmap.py, handles the light side).
    exempt = bent if bent is not None else np.zeros(n, np.bool_)
    if unguarded is not None:
        exempt = exempt | unguarded
    face_shading_normals(ns, ng, front, d, exempt)
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
                      offset=offset, bary=bary, alpha=alpha,
                      n_smooth=n_smooth, params=scalar_params(table, sg, mat, prim, u, v),
                      emission=(hit_emission(table, sg, mat, prim, u, v)
                                if table.emission.any() else np.broadcast_to(_NO_LIGHT, (n, 3))))


def reads_footprint(table: MaterialTable) -> bool:
    """Whether surface_hit's footprint can change a hit of this table: some material's
    normal map is a Bump or a displacement's DisplacedNormals (its bump, or the Bump after
    it), the only readers (_perturb). Without one the camera paths hand their gathers no
    footprints to carry (integrator._trace_paths; slow52)."""
    return any(isinstance(m, (Bump, DisplacedNormals)) for m in (table.normal_maps or ()))


def _perturb(nmap, geo, prim, u, v, ns, sel, footprint):
    """The shading normals nmap (a NormalMap, Bump, Bevel) gives the rows sel; a Bump
    over the rays' footprints where they are known."""
    if footprint is not None and isinstance(nmap, Bump):
        return nmap.perturb(geo, prim[sel], u[sel], v[sel], ns[sel], footprint=footprint[sel])
    return nmap.perturb(geo, prim[sel], u[sel], v[sel], ns[sel])


# Emission rows where no material emits: one zero row seen N times (nothing to gather).
_NO_LIGHT = np.zeros(3)
_NO_LIGHT.flags.writeable = False


def plain_surfaces(table: MaterialTable) -> bool:
    """Whether no material has per-hit nodes (normal map, colour texture, alpha texture,
    texture-driven scalar input) between the hit's geometry and its lobes: then
    surface_hit_lobes computes a bounce's surface data and lobes in one kernel."""
    return not any(node is not None
                   for nodes in (table.normal_maps, table.textures, table.alpha_textures,
                                 getattr(table, "scalar_textures", None))
                   for node in (nodes or ()))


def surface_hit_lobes(geo: Geometry, table: MaterialTable, prim, u, v, d, tp, want_glossy,
                      out, material=None, blur=None,
                      mean_weights=False) -> tuple[SurfaceHit, int]:
    """surface_hit and camerakernels.shade_lobes on N hits in one kernel
    (camerakernels.surface_lobes), for tables with plain_surfaces: (the SurfaceHit, with
    prm set to out's packed lobes, K the number of rows to shade). tp (N,3) throughputs,
    want_glossy as shade_lobes; out = (prm, sel, p, q, psum, glossy, rows, wd) the
    arrays shade_lobes writes (integrator.BounceBuffers.take(N)), written as it writes
    them. Same bits as surface_hit then shade_lobes (tests/test_fused_camera.py).
    material: as surface_hit's; blur (N,) Cycles' Filter Glossy alpha per hit
    (engine/filterglossy.py) or None: none; mean_weights: shade_lobes' (the lobe choice
    by the albedos' mean channel, the camera's first hits)."""
    n = len(prim)
    u, v, d = _as_float64(u, v, d)
    p, ng, ns, base, front, mat, offset, bary = _hit_outputs(geo, n)
    wo = np.empty((n, 3))
    prm, sel, pw, q, psum, glossy, rows, wd = out
    idx, tabs = raymaterials.hit_tables(geo, prim, material, "v0", "e1", "e2",
                                        "corner_normals", "material")
    k = surface_lobes(idx, u, v, d, *tabs, table.base_color, table.closure_params,
                      np.ascontiguousarray(table.alpha, np.float64),
                      np.ascontiguousarray(tp, np.float64), bool(want_glossy), p, ng, ns, wo,
                      front, mat, base, offset, bary, prm, sel, q, pw, psum, glossy, rows, wd,
                      NO_BLUR if blur is None else np.ascontiguousarray(blur, np.float64),
                      bool(mean_weights))
    _offset_floor(geo, prim, p, ng, offset)
    if table.emission.any():
        emission = hit_emission(table, ShadingGeometry(geo, ns, wo, ~front), mat, prim, u, v)
    else:
        emission = np.broadcast_to(_NO_LIGHT, (n, 3))
    return SurfaceHit(p=p, ng=ng, ns=ns, wo=wo, front=front, mat=mat, base=base, prim=prim,
                      offset=offset, bary=bary, prm=prm, emission=emission), k


def closures(table: MaterialTable, hit: SurfaceHit, geo=None):
    """The hits' lobes as engine/closures/principled.py builds them (Cycles' Principled v2
    layering): (packed per-hit parameters (N, principled.N_PACK), estimated albedo of each
    lobe (N, len(LOBE_NAMES), 3)). Cached on the hit. One compiled kernel
    (camerakernels.hit_closures: the view cosine, Cycles' glossy normal, the closures'
    set-up). geo: the Geometry, for the tangents of anisotropic lobes (engine/anisotropy.py;
    None: those lobes stay isotropic)."""
    # (lobe_albedo first: a HitRows view without it then copies no prm rows it replaces)
    if hit.lobe_albedo is None or hit.prm is None:
        n = len(hit.mat)
        per_hit = hit.params is not None  # texture-driven scalar inputs: a row per hit
        alpha = _NO_ALPHA if hit.alpha is None else np.ascontiguousarray(hit.alpha, np.float64)
        prm = np.empty((n, pr.N_PACK))
        albedo = np.empty((n, pr.N_LOBES, 3))
        hit_closures(hit.ns, hit.ng, hit.wo, hit.mat,
                     hit.params if per_hit else table.closure_params, per_hit, hit.base,
                     hit.front, np.ascontiguousarray(table.alpha, np.float64), alpha, prm,
                     albedo, NO_BLUR)
        if geo is not None:
            set_hit_tangents(geo, hit.params if per_hit else table.closure_params, hit, prm)
        hit.prm, hit.lobe_albedo = prm, albedo
    return hit.prm, hit.lobe_albedo


_NO_ALPHA = np.zeros(0)  # hit_closures' per-hit alpha when the materials' constants apply


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
