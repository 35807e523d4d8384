"""Scene model: meshes, materials, lights, camera and background as flat numpy arrays.

Everything the renderer needs is validated here, at the boundary, so the rest of the
engine can assume finite numbers and valid indices. Structural mistakes (wrong shapes,
unknown material names) raise SceneError naming the object; repairable defects (NaN
vertices, out-of-range or degenerate faces) drop the offending faces and add a warning
naming the object, so a scene with one broken mesh still renders.

Units follow Blender/Cycles (see docs/units.md): light power in watts, sun strength in
W/m^2, emission as radiance, metres for lengths.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .displacement import METHODS as DISPLACEMENT_METHODS, DisplacedNormals
from .bump import Bump
from .normalmap import NormalMap
from .panorama import Panorama
from .textures import ColorAttribute, ImageTexture, TextureError, as_texture

__all__ = [
    "SceneError", "Material", "Mesh", "Prototype", "Light", "Camera", "Scene",
    "POINT", "SPOT", "AREA", "SUN", "RECTANGLE", "DISK", "EMISSION_SAMPLING",
    "emission_sides",
]

POINT, SPOT, AREA, SUN = "POINT", "SPOT", "AREA", "SUN"
RECTANGLE, DISK = "RECTANGLE", "DISK"  # area shapes; SQUARE/ELLIPSE map onto these
MIN_SPREAD = math.radians(1.0)  # narrowest area-light spread sampled (see Light)


class SceneError(ValueError):
    """Invalid scene input; the message names the object and what is wrong."""


# The engine traces in float32 (Embree): a value beyond float32's range is as infinite
# as inf itself, so it is refused as such (1e39 W would render black, 1e308 m crashed
# the BVH build).
FLOAT32_MAX = float(np.finfo(np.float32).max)


def representable(arr) -> np.ndarray:
    """Elementwise: finite and within float32's range (|x| <= 3.4e38)."""
    arr = np.asarray(arr, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        return np.isfinite(arr) & (np.abs(arr) <= FLOAT32_MAX)


def _vec3(value, what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.size == 1:
        arr = np.repeat(arr, 3)
    if arr.shape != (3,):
        raise SceneError(f"{what}: expected 3 numbers, got {np.asarray(value).shape}")
    if not np.all(representable(arr)):
        raise SceneError(f"{what}: values must be finite (within float32's +-3.4e38), "
                         f"got {arr.tolist()}")
    return arr


def euler_rotation(angles) -> np.ndarray:
    """(3,3) rotation matrix of Blender's XYZ Euler angles (radians): Rz @ Ry @ Rx."""
    rx, ry, rz = (float(a) for a in angles)
    cx, sx, cy, sy, cz, sz = (math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry),
                              math.cos(rz), math.sin(rz))
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def _finite(value, what: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and abs(v) <= FLOAT32_MAX):
        raise SceneError(f"{what}: must be finite (within float32's +-3.4e38), got {value}")
    return v


def _names(value, what: str) -> list:
    """A list of object names (a single name is a list of one)."""
    if isinstance(value, str):
        return [value]
    try:
        names = [str(v) for v in value]
    except TypeError:
        raise SceneError(f"{what}: expected a list of object names, got {value!r}") from None
    return names


def _aov_outputs(aovs, who) -> dict:
    """Material.aovs checked: {name: {"color": node or (3,) float64, "value": node or
    float}} (either key may be missing). Raises SceneError naming the material."""
    out = {}
    for name, outputs in dict(aovs or {}).items():
        if not isinstance(name, str) or not name:
            raise SceneError(f"{who} aovs: an AOV name must be a non-empty string, got "
                             f"{name!r}")
        checked = {}
        for kind, value in dict(outputs).items():
            if kind not in ("color", "value"):
                raise SceneError(f"{who} aovs '{name}': expected 'color' or 'value' "
                                 f"outputs, got {kind!r}")
            if hasattr(value, "evaluate"):
                checked[kind] = value
            elif kind == "color":
                checked[kind] = _vec3(value, f"{who} aovs '{name}' color")
            else:
                checked[kind] = float(value)
                if not math.isfinite(checked[kind]):
                    raise SceneError(f"{who} aovs '{name}' value: must be finite, got "
                                     f"{value!r}")
        out[name] = checked
    return out


@dataclass
class Material:
    """A Principled-v2 surface with Cycles' meaning (engine/closures/principled.py builds
    its layers, top first):
      translucent       share of Lambertian diffuse transmission (Cycles' Translucent
                        BSDF: light through the surface, spread as cosine on the far
                        side), coloured translucent_color (or the base colour when None;
                        a Mix of Diffuse and Translucent keeps both colours); every layer
                        below keeps 1 - translucent
      sheen_weight      Cycles' microfiber sheen (sheen_roughness, tinted sheen_tint)
      coat_weight       a clear dielectric coat (coat_roughness, coat_ior) tinting what is
                        below it with coat_tint along the refracted path
      metallic          GGX metal with F82-tint Fresnel (f0 = base colour, tint =
                        specular_tint); node="glossy": a constant reflectance,
                        glossy_color (or the base colour when None; a Mix of Diffuse and
                        Glossy keeps both colours)
      transmission      GGX glass (reflection + refraction; transmission tinted
                        sqrt(base colour), or the colour for node="glass";
                        node="refraction": refraction alone, the colour, no Fresnel)
      specular          weight of the dielectric specular layer over the diffuse base
                        (Principled: 1; F0 from ior x 2 x specular_ior_level, tinted by
                        specular_tint; 0: pure Lambert)
      diffuse           Lambert, base colour x what the layers above leave
    Microfacet lobes use GGX with alpha = roughness^2; multiscatter=True adds Cycles'
    multiple-scattering energy compensation (Multiscatter GGX, Principled's default).
    `anisotropic` stretches the metal and specular lobes along a tangent (Cycles'
    anisotropic GGX, principled.aniso_alphas): Principled's Anisotropic (0..1), or the
    Glossy BSDF's Anisotropy (-1..1) for node="glossy"; `anisotropic_rotation` turns the
    tangent about the normal (turns). The tangent is Blender's default, radial about the
    object's Z axis (engine/anisotropy.py).
    `alpha` < 1 lets the rest of the light pass straight through (Transparent BSDF),
    tinted by `transparent_tint` (the Transparent BSDF's Color: the pass transmits
    (1 - alpha) x tint per channel, for camera rays, shadow rays and photons alike; a
    tint above 1 is the sum of an Add Shader's Transparent BSDFs beside a surface share,
    as Cycles sums closure weights: (1 - alpha) x tint is clamped to 1 per channel, the
    tint to 1 where an alpha texture is set).
    `emission` is radiance (W/m^2/sr) leaving the front and back of the surface.
    `texture` is an optional engine.textures.ImageTexture (or a bare HxWx3 linear float
    image: Repeat, Linear) or ColorAttribute, multiplied onto base colour per hit.
    `normal_map` is an optional engine.normalmap.NormalMap, Bump or engine.bevel.Bevel
    (or an engine.displacement.DisplacedNormals: a displacement's bump, then one of
    those) perturbing the shading normal.
    `alpha_texture` is an optional node (evaluate(geo, prim, u, v): an
    engine.shadernodes.ImageLookup of an image's Alpha, a Math node, ...) whose value per
    hit multiplies `alpha`: alpha cut-outs (leaves, fences) for camera rays, shadow rays
    and photons alike (engine/textures.py, material_alpha).
    `emission_texture` is an optional colour node multiplied onto `emission` per hit
    (Emission Color fed by a texture): the camera sees it per hit; as a mesh light each
    triangle emits its average (geometry.emissive_triangles).
    `closure_weight` scales every BSDF lobe (not the pass lobe, not the emission): Cycles'
    closure weight, 2 for an Add Shader of two surfaces (it sums their closures; the
    layers above describe their even mix).
    `scalar_textures` optionally maps scalar inputs (SCALAR_INPUTS: roughness, metallic,
    ...) to nodes evaluated per hit whose value replaces the constant there, camera and
    photon pass alike (engine/textures.py, scalar_params; docs/textures.md); a colour input
    (COLOR_INPUTS: the specular, coat and sheen tints) takes the node's RGB.
    `pass_index`: Blender's material.pass_index, written by the Material Index data
    pass (engine/datapasses.py); it changes no shading.
    `emission_sampling`: Blender's material.cycles.emission_sampling (EMISSION_SAMPLING): which
    sides of the emission shadow rays sample (emission_sides); the emission itself leaves
    both sides in every mode, the other sides' light arriving by sampled rays alone.
    `absorption` (3,) 1/m: the homogeneous absorption coefficient sigma_a per channel of
    the medium inside the object (a Volume Absorption or Principled Volume on the
    Material Output's Volume): light travelling a distance d (world units, object scale
    included) inside it keeps exp(-sigma_a d) (Beer-Lambert), for camera paths, photons
    and shadow rays alike (engine/media.py; docs/compatibility.md, Volume absorption).
    `scattering` (3,) 1/m: the medium's scattering coefficient sigma_s per channel (Volume
    Scatter density x colour, Principled Volume density x Color: Cycles'
    svm_node_principled_volume); its extinction is sigma_a + sigma_s, and the light it
    scatters follows the Henyey-Greenstein phase function of `anisotropy` g in (-1, 1)
    (Cycles' volume_henyey_greenstein; engine/volumescatter.py).
    `volume_emission` (3,) W m^-2 sr^-1 per metre: the radiance the medium emits per unit
    length of a ray inside it (an Emission shader on the Material Output's Volume: Color
    x Strength; Principled Volume: Emission Strength x Emission Color plus its
    blackbody; Cycles' emission_setup in a volume shader); a segment of length S adds
    e (1 - exp(-sigma_t S)) / sigma_t (engine/volumeemission.py).
    `volume_only`: the material has a volume but no surface (Surface unlinked): Cycles
    renders the surface invisible, rays pass it unbent and only the medium acts; here
    that is a transparent pass (alpha 0, white tint, no emission, black base).
    `density_texture`: a node (engine/shadernodes.py, evaluate -> (N,) or (N,3)) whose
    value at a point inside the object scales the medium: sigma(p) = max(value, 0) x
    absorption / scattering, which are then the coefficients at density 1 (a textured
    Density socket: clouds, smoke; engine/heterogeneous.py). None: homogeneous.
    `volume_emission_texture`: a node whose value at a point inside the object is the
    medium's emission there ((N,3) or (N,), W m^-2 sr^-1 per metre, clipped at 0; a
    textured Emission Strength / Color / Blackbody: a glowing cloud, fire); it replaces
    `volume_emission` (engine/volumefields.py). None: `volume_emission` everywhere.
    `albedo_texture`: a node whose value at a point is the medium's single-scattering
    albedo sigma_s / sigma_t there ((N,3), clipped to 0..1; Principled Volume's textured
    Color with a black Absorption Color: a coloured cloud); the extinction stays
    absorption + scattering (x the density texture), only its split between them varies
    (engine/volumefields.py). None: scattering / (absorption + scattering) everywhere.
    `displacement`, `displacement_method`: Cycles' true displacement (Material > Settings >
    Displacement): with "DISPLACEMENT" (Displacement Only) or "BOTH" (Displacement and
    Bump), the vertices of this material's faces move by the world-space vectors (m) of
    `displacement` (an engine node: engine.displacement.Displacement, VectorDisplacement
    or any vector / value node) before the triangles are merged, as Cycles displaces
    mesh vertices (engine/displacement.displace_meshes; "DISPLACEMENT" recomputes the
    normals, "BOTH" keeps them and bumps through `normal_map`); "BUMP" (Blender's
    default) moves nothing: the bump is `normal_map`'s DisplacedNormals alone.
    `aovs`: Cycles' AOV Output nodes: {AOV name: {"color": node or RGB (3,), "value":
    node or float}}, what the material writes into the Shader AOV passes of that name
    (engine/datapasses.py); a node is an engine/shadernodes node evaluated at the hits.
    `ray_variants`: {"camera" | "glossy" | "transmission" | "shadow": Material} the
    surface other ray classes meet (Cycles' Light Path node in the material: a window
    transparent to shadow rays, a lamp the camera does not see); this material is what
    diffuse rays, photons and light sampling meet (engine/raymaterials.py). None: one
    material for every ray.
    `holdout`: camera rays that meet the surface see a hole (alpha 0, no colour), as an
    object's holdout (Mesh.holdout) does: Cycles' Holdout shader, as the camera variant
    of Mix Shader(Is Camera Ray, Emission, Holdout) (addon/lightpath.py).
    """

    name: str = "default"
    base_color: tuple | np.ndarray = (0.8, 0.8, 0.8)
    metallic: float = 0.0
    roughness: float = 0.0
    transmission: float = 0.0
    ior: float = 1.5
    specular: float = 0.0
    emission: tuple | np.ndarray = (0.0, 0.0, 0.0)
    alpha: float = 1.0
    specular_ior_level: float = 0.5
    specular_tint: tuple | np.ndarray = (1.0, 1.0, 1.0)
    coat_weight: float = 0.0
    coat_roughness: float = 0.03
    coat_ior: float = 1.5
    coat_tint: tuple | np.ndarray = (1.0, 1.0, 1.0)
    multiscatter: bool = True
    node: str = "principled"
    glossy_color: tuple | np.ndarray | None = None
    sheen_weight: float = 0.0
    sheen_roughness: float = 0.5
    sheen_tint: tuple | np.ndarray = (1.0, 1.0, 1.0)
    translucent: float = 0.0
    translucent_color: tuple | np.ndarray | None = None
    transparent_tint: tuple | np.ndarray = (1.0, 1.0, 1.0)
    texture: ImageTexture | ColorAttribute | np.ndarray | None = None
    normal_map: NormalMap | Bump | DisplacedNormals | None = None
    alpha_texture: object | None = None
    scalar_textures: dict | None = None
    emission_texture: object | None = None
    closure_weight: float = 1.0
    anisotropic: float = 0.0
    anisotropic_rotation: float = 0.0
    pass_index: int = 0
    emission_sampling: str = "AUTO"
    absorption: tuple | np.ndarray = (0.0, 0.0, 0.0)
    scattering: tuple | np.ndarray = (0.0, 0.0, 0.0)
    anisotropy: float = 0.0
    volume_emission: tuple | np.ndarray = (0.0, 0.0, 0.0)
    volume_only: bool = False
    density_texture: object | None = None
    volume_emission_texture: object | None = None
    albedo_texture: object | None = None
    displacement: object | None = None
    displacement_method: str = "BUMP"
    aovs: dict = field(default_factory=dict)
    ray_variants: dict | None = None
    holdout: bool = False
    # Cycles' random-walk BSSRDF (engine/subsurfacewalk.SubsurfaceParams): camera paths
    # walk beneath the surface; base_color then holds the diffuse stand-in the photons
    # and gather rays see (engine/subsurface.py). None: no subsurface closure.
    subsurface: object | None = None
    warnings: list = field(default_factory=list, repr=False)

    def __post_init__(self):
        who = f"material '{self.name}'"
        if self.alpha_texture is not None and not hasattr(self.alpha_texture, "evaluate"):
            raise SceneError(f"{who} alpha_texture: expected a node with evaluate(geo, prim, "
                             f"u, v) (engine.shadernodes), got "
                             f"{type(self.alpha_texture).__name__}")
        if self.scalar_textures:
            for key, node in self.scalar_textures.items():
                if key not in SCALAR_INPUTS:
                    raise SceneError(f"{who} scalar_textures: unknown input {key!r} "
                                     f"(expected one of {', '.join(SCALAR_INPUTS)})")
                if not hasattr(node, "evaluate"):
                    raise SceneError(f"{who} scalar_textures[{key!r}]: expected a node with "
                                     f"evaluate(geo, prim, u, v), got {type(node).__name__}")
        self.scalar_textures = dict(self.scalar_textures) if self.scalar_textures else None
        if self.emission_texture is not None and not hasattr(self.emission_texture, "evaluate"):
            raise SceneError(f"{who} emission_texture: expected a node with evaluate(geo, "
                             f"prim, u, v), got {type(self.emission_texture).__name__}")
        if self.ray_variants:
            from .raymaterials import VARIANT_CLASSES
            for key, var in self.ray_variants.items():
                if key not in VARIANT_CLASSES:
                    raise SceneError(f"{who} ray_variants: unknown ray class {key!r} "
                                     f"(expected one of {', '.join(VARIANT_CLASSES)})")
                if not isinstance(var, Material) or var.ray_variants:
                    raise SceneError(f"{who} ray_variants[{key!r}]: expected an engine "
                                     "Material without variants of its own")
            self.ray_variants = dict(self.ray_variants)
        else:
            self.ray_variants = None
        self.base_color = _vec3(self.base_color, f"{who} base_color")
        self.emission = _vec3(self.emission, f"{who} emission")
        if np.any(self.emission < 0):
            raise SceneError(f"{who} emission: must be >= 0, got {self.emission.tolist()}")
        if np.any(self.base_color < 0):
            raise SceneError(f"{who} base_color: must be >= 0, got {self.base_color.tolist()}")
        if np.any(self.base_color > 1):
            # Kept, as Cycles keeps it (its diffuse closure takes max(colour, 0); the metal
            # and glass lobes clip to 1 themselves, closures/principled.py).
            self.warnings.append(f"{who}: base colour {self.base_color.round(3).tolist()} "
                                 "above 1 reflects more light than it receives (as in "
                                 "Cycles)")
        for attr in ("metallic", "roughness", "transmission", "specular", "alpha",
                     "coat_roughness", "sheen_roughness", "translucent"):
            v = _finite(getattr(self, attr), f"{who} {attr}")
            setattr(self, attr, min(max(v, 0.0), 1.0))
        for attr in ("anisotropic", "anisotropic_rotation"):
            setattr(self, attr, _finite(getattr(self, attr), f"{who} {attr}"))
        self.anisotropic = min(max(self.anisotropic, -1.0), 1.0)
        for attr in ("specular_ior_level", "coat_weight", "sheen_weight", "closure_weight"):
            v = _finite(getattr(self, attr), f"{who} {attr}")
            if v < 0:
                raise SceneError(f"{who} {attr}: must be >= 0, got {v}")
            setattr(self, attr, v)
        for attr in ("specular_tint", "coat_tint", "sheen_tint"):
            v = _vec3(getattr(self, attr), f"{who} {attr}")
            if np.any(v < 0):
                raise SceneError(f"{who} {attr}: must be >= 0, got {v.tolist()}")
            setattr(self, attr, v)
        tint = _vec3(self.transparent_tint, f"{who} transparent_tint")
        if np.any(tint < 0):
            raise SceneError(f"{who} transparent_tint: must be >= 0, got {tint.tolist()}")
        # The pass transmits (1 - alpha) x tint: a tint above 1 is a sum of Transparent
        # BSDFs beside a surface share (an Add Shader, Cycles' summed closure weights),
        # kept while the pass lets through no more light than arrives; an alpha texture
        # lowers alpha per hit, so there the tint itself stays within 1.
        a = min(max(float(self.alpha), 0.0), 1.0)
        top = 1.0 / (1.0 - a) if self.alpha_texture is None and a < 1.0 else 1.0
        if np.any(tint > top * (1.0 + 1e-12)):
            # A pass that lets more light through than arrives would create energy.
            self.warnings.append(
                f"{who}: transparent tint {tint.round(3).tolist()} x (1 - alpha) above 1 "
                "clamped to 1 (it would create energy)" if self.alpha_texture is None else
                f"{who}: transparent tint {tint.round(3).tolist()} above 1 with an alpha "
                "texture (alpha varies per hit) clamped to 1 (it could create energy)")
        self.transparent_tint = np.minimum(tint, top)
        self.ior = _finite(self.ior, f"{who} ior")
        if self.ior <= 0:
            raise SceneError(f"{who} ior: must be > 0, got {self.ior}")
        self.coat_ior = _finite(self.coat_ior, f"{who} coat_ior")
        if self.coat_ior < 1:
            raise SceneError(f"{who} coat_ior: must be >= 1, got {self.coat_ior}")
        mode = str(self.emission_sampling).upper()
        if mode not in EMISSION_SAMPLING:
            raise SceneError(f"{who} emission_sampling: expected one of "
                             f"{', '.join(EMISSION_SAMPLING)}, got {self.emission_sampling!r}")
        self.emission_sampling = mode
        self.absorption = _vec3(self.absorption, f"{who} absorption")
        if np.any(self.absorption < 0):
            raise SceneError(f"{who} absorption: must be >= 0 (1/m), got "
                             f"{self.absorption.tolist()}")
        self.scattering = _vec3(self.scattering, f"{who} scattering")
        if np.any(self.scattering < 0):
            raise SceneError(f"{who} scattering: must be >= 0 (1/m), got "
                             f"{self.scattering.tolist()}")
        self.anisotropy = float(self.anisotropy)
        if not -1.0 < self.anisotropy < 1.0:
            raise SceneError(f"{who} anisotropy: must lie in (-1, 1), got {self.anisotropy}")
        self.volume_emission = _vec3(self.volume_emission, f"{who} volume_emission")
        if np.any(self.volume_emission < 0):
            raise SceneError(f"{who} volume_emission: must be >= 0 (W/m^2/sr per m), got "
                             f"{self.volume_emission.tolist()}")
        self.volume_only = bool(self.volume_only)
        if self.density_texture is not None and not hasattr(self.density_texture,
                                                            "evaluate"):
            raise SceneError(f"{who} density_texture: expected a node with evaluate(), got "
                             f"{type(self.density_texture).__name__}")
        for name in ("volume_emission_texture", "albedo_texture"):
            tex = getattr(self, name)
            if tex is not None and not hasattr(tex, "evaluate"):
                raise SceneError(f"{who} {name}: expected a node with evaluate(), got "
                                 f"{type(tex).__name__}")
        if self.volume_only:
            # No surface: every ray passes it unbent and untinted (a transparent pass).
            self.alpha = 0.0
            self.alpha_texture = None
            self.transparent_tint = np.ones(3)
            self.base_color = np.zeros(3)
            self.emission = np.zeros(3)
            self.emission_texture = None
        if self.node not in MATERIAL_NODES:
            raise SceneError(f"{who} node: expected one of {', '.join(MATERIAL_NODES)}, got "
                             f"{self.node!r}")
        self.multiscatter = bool(self.multiscatter)
        if self.glossy_color is not None:
            self.glossy_color = np.clip(_vec3(self.glossy_color, f"{who} glossy_color"), 0.0,
                                        1.0)
        if self.translucent_color is not None:
            tc = _vec3(self.translucent_color, f"{who} translucent_color")
            if np.any(tc < 0):
                raise SceneError(f"{who} translucent_color: must be >= 0, got {tc.tolist()}")
            self.translucent_color = tc
        if self.texture is not None:
            try:
                self.texture = as_texture(self.texture, name=f"{self.name} texture")
            except TextureError as exc:
                raise SceneError(f"{who} {exc}") from None
        if self.displacement_method not in DISPLACEMENT_METHODS:
            raise SceneError(f"{who} displacement_method: expected one of "
                             f"{DISPLACEMENT_METHODS}, got {self.displacement_method!r}")
        if self.displacement is not None and not hasattr(self.displacement, "evaluate"):
            raise SceneError(f"{who} displacement: expected an engine node with evaluate() "
                             "(engine.displacement.Displacement, VectorDisplacement, any "
                             f"vector node), got {type(self.displacement).__name__}")
        from .bevel import Bevel  # (bevel -> ambientocclusion -> geometry imports scene)
        if self.normal_map is not None and not isinstance(
                self.normal_map, (NormalMap, Bump, Bevel, DisplacedNormals)):
            raise SceneError(f"{who} normal_map: expected an engine.normalmap.NormalMap, Bump, "
                             "engine.bevel.Bevel or engine.displacement.DisplacedNormals, got "
                             f"{type(self.normal_map).__name__}")
        self.aovs = _aov_outputs(self.aovs, who)

    @property
    def is_emissive(self) -> bool:
        return bool(np.any(self.emission > 0))


# How the colour enters the metal and glass lobes (engine/closures/principled.py):
# Principled BSDF, Glossy BSDF (colour = constant reflectance), Glass BSDF (colour tints
# reflection and refraction), Refraction BSDF (the glass lobe's refraction alone, colour x
# refraction, no Fresnel).
MATERIAL_NODES = ("principled", "glossy", "glass", "refraction")

# Material > Settings > Emission Sampling (Cycles' EmissionSampling, scene/shader.h):
# which sides of an emissive surface light sampling covers (shadow rays with multiple
# importance sampling); the sides it leaves out reach the scene through sampled rays
# only (gather rays, glossy continuations: their hits count in full) and photons.
EMISSION_SAMPLING = ("NONE", "AUTO", "FRONT", "BACK", "FRONT_BACK")
SIDE_FRONT, SIDE_BACK = 1, 2  # bits of emission_sides: the side the normal points to, the other
# Cycles' Shader::estimate_emission: AUTO samples both sides when the largest channel of
# the emission's estimate exceeds this (W/m^2/sr), none below ("weakly emitting" shaders).
AUTO_EMISSION_THRESHOLD = 0.5


def emission_sides(mode: str, emission) -> int:
    """Sides of an emissive material that light sampling covers: SIDE_FRONT | SIDE_BACK
    bits (0: none, 3: both) for Emission Sampling `mode` (EMISSION_SAMPLING) and the
    material's emission (3,) radiance in W/m^2/sr (its constant: colour x strength, 1 for
    a colour fed by a texture, as Cycles' output_estimate_emission counts a linked colour).
    AUTO follows Cycles' Shader::estimate_emission (intern/cycles/scene/shader.cpp): both
    sides when max(emission) > AUTO_EMISSION_THRESHOLD, else none; black emission: none."""
    e = np.asarray(emission, np.float64)
    if not np.any(e > 0) or mode == "NONE":
        return 0
    if mode == "AUTO":
        return SIDE_FRONT | SIDE_BACK if float(e.max()) > AUTO_EMISSION_THRESHOLD else 0
    return {"FRONT": SIDE_FRONT, "BACK": SIDE_BACK, "FRONT_BACK": SIDE_FRONT | SIDE_BACK}[mode]
# Blender's world.mist_settings.falloff -> Cycles' film mist_falloff exponent
# (intern/cycles/blender/sync.cpp).
MIST_FALLOFF = {"QUADRATIC": 2.0, "LINEAR": 1.0, "INVERSE_QUADRATIC": 0.5}

# Scalar inputs a node may drive per hit (Material.scalar_textures), with the range
# Cycles clamps them to (svm/closure.h: saturatef, or fmaxf(x, 0) for the weights and the
# specular IOR level).
SCALAR_INPUTS = {"roughness": (0.0, 1.0), "metallic": (0.0, 1.0), "specular": (0.0, 1.0),
                 "transmission": (0.0, 1.0), "specular_ior_level": (0.0, np.inf),
                 "coat_weight": (0.0, np.inf), "coat_roughness": (0.0, 1.0),
                 "sheen_weight": (0.0, np.inf), "sheen_roughness": (0.0, 1.0),
                 # Per hit where a Mix Shader picks one of two surfaces whole
                 # (addon/materials.py _mix_per_hit): each side's own value, clamped as the
                 # add-on clamps the constants (IOR > 0 as the kernels' max(ior, 1e-5), the
                 # coat's IOR >= 1, a 0 / 1 distribution flag, anisotropy in [-1, 1]).
                 "ior": (1e-5, np.inf), "coat_ior": (1.0, np.inf), "multiscatter": (0.0, 1.0),
                 "anisotropic": (-1.0, 1.0), "anisotropic_rotation": (-np.inf, np.inf),
                 # The picked side's closure model (geometry.node_code: 0 Principled,
                 # 1 Glossy, 2 Glass, 3 Refraction BSDF).
                 "node": (0.0, 3.0),
                 # Colours (three columns each, per channel >= 0).
                 "specular_tint": (0.0, np.inf), "coat_tint": (0.0, np.inf),
                 "sheen_tint": (0.0, np.inf)}
# The SCALAR_INPUTS that are colours: a colour node's RGB per hit, not its luminance.
COLOR_INPUTS = ("specular_tint", "coat_tint", "sheen_tint")


# The paper's predefined materials (Figures 3-4), in our lobe model.
def predefined_materials() -> dict[str, Material]:
    return {
        "red_plastic": Material("red_plastic", (0.8, 0.05, 0.05), specular=1.0, ior=1.5),
        "green_plastic": Material("green_plastic", (0.05, 0.6, 0.05), specular=1.0, ior=1.5),
        "blue_plastic": Material("blue_plastic", (0.05, 0.05, 0.8), specular=1.0, ior=1.5),
        "white_plastic": Material("white_plastic", (0.8, 0.8, 0.8), specular=1.0, ior=1.5),
        "white_plastic_dull": Material("white_plastic_dull", (0.75, 0.75, 0.75)),
        "white_diffuse": Material("white_diffuse", (0.8, 0.8, 0.8)),
        "red_diffuse": Material("red_diffuse", (0.75, 0.1, 0.1)),
        "green_diffuse": Material("green_diffuse", (0.1, 0.6, 0.1)),
        "glass": Material("glass", (1.0, 1.0, 1.0), transmission=1.0, ior=1.5),
        "mirror": Material("mirror", (0.95, 0.95, 0.95), metallic=1.0),
        "chrome": Material("chrome", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.15),
        "black": Material("black", (0.0, 0.0, 0.0)),
    }


@dataclass
class Mesh:
    """A triangle mesh in world space (the exporter applies object transforms).

    vertices  (V,3) float      faces (F,3) int (triangles; quads must be split first)
    normals   optional (V,3) per vertex or (F,3,3) per face corner (smooth / custom split
              normals); None = flat shading
    uvs       optional (V,2) per vertex or (F,3,2) per face corner
    colors    optional colour attribute (vertex colours), linear RGB(A): (V,3|4) per vertex
              or (F,3,3|4) per face corner; read by engine.textures.ColorAttribute
    coordinates  optional {name: (F,3,3)} per-corner texture coordinates, e.g. Blender's
              "generated" and "object" (engine.shadernodes.Coordinates)
    material  one material name, or material_ids (F,) int indexing `materials` (names)
    visible_camera, visible_diffuse, visible_glossy, visible_transmission, visible_shadow
              ray visibility with Cycles' meaning (Object > Visibility > Ray Visibility):
              a ray of that kind passes through the mesh as if it were not there. Camera
              rays and the rays that continue them through transparent surfaces are
              camera rays; shadow rays are the rays to lights; final-gather rays are
              diffuse rays; mirror / coat reflections are glossy, refractions transmission
              rays (docs/scene_format.md, "Ray visibility", also for photons).
    holdout   the mesh cuts a hole in the image: camera rays (and their continuations
              through transparent surfaces) that hit it give alpha 0 and no colour; every
              other ray sees its material, so it still bounces and reflects light (Cycles'
              holdout applies only to rays that can reach the transparent background)
    shadow_catcher  Blender's Object > Visibility > Shadow Catcher: camera rays that meet
              the mesh first show only the shadows (and, in the Shadow Catcher pass, the
              light) the other objects cast on it, as Cycles' shadow catcher does; every
              other ray sees it as an ordinary surface (engine/shadowcatcher.py)
    shadow_terminator_offset  Cycles' object setting Shadow Terminator > Geometry Offset
              (`shadow_terminator_geometry_offset`, >= 0, Blender's default 0.1): shadow
              rays from smooth-shaded triangles at grazing light leave from the smooth
              surface the normals describe, not the flat facet (engine/rayoffset.py)
    shadow_terminator_shading_offset  Cycles' Shadow Terminator > Shading Offset (>= 0,
              < 2, default 0): pushes the terminator of direct light towards the light
              (Cycles' shift_cos_in, appleseed's fix)
    cryptomatte_object, cryptomatte_asset  the names Cryptomatte's object and asset layers
              give this mesh (engine/cryptomatte.py; None: `name`, and the asset the
              object's): Blender's object name, which instances of one object share, and
              its topmost parent's
    receivers, non_receivers  Light Linking of an emitting mesh (its material emits):
              as Light.receivers / non_receivers, the meshes its emission lights directly
              (None / []: every one; engine/lightlinking.py)
    prototype, matrix  optional instance record: this mesh is `prototype` (object space)
              placed by the (4,4) or (3,4) object-to-world `matrix`; vertices and faces
              are then that placement (faces as the prototype's, corners 0, 2, 1 when the
              matrix mirrors). Meshes sharing a prototype may be traced with one BVH of
              the prototype (engine/instancing.py); a record that does not match the
              mesh is ignored (the mesh is traced as it is) with a warning.
              vertices=None (and no faces, normals, UVs, colours or coordinates) makes
              the mesh a placement without a world-space copy (Mesh.place): faces,
              material slots, normals and UVs are the prototype's (Prototype), the mesh's
              `materials` fill its slots; the copy is built only if the scene is
              expanded (engine/resources.two_level_instances decides).
    pass_index  Blender's object.pass_index (an instance's own), written by the Object
              Index data pass (engine/datapasses.py) and read by an Object Info node
    random    the Object Info node's Random output, 0..1: Blender's instance random_id
              / (2^32 - 1) (Cycles' object random_number; an instance's own)
    object_color  the Object Info node's Color and Alpha: Blender's object.color RGBA
    location  the Object Info node's Location: the object's (an instance's own) origin in
              world space, m (the translation of its object-to-world matrix)
    object_linear  the linear part (3x3, row-major nested tuples) of the object's (an
              instance's own) object-to-world matrix: a Displacement node's Object space
              (engine/displacement.py); None: the identity
    object_attributes  {name: RGBA} the Attribute node of type Object / Instancer reads
              per object (Blender's object, instancer or mesh property of that name);
              a name a mesh lacks reads (0, 0, 0, 0)
    volume_grids  {name: engine.voxelgrid.VoxelGrid} a Volume object's grids (world
              space) that its material's nodes read (voxelgrid.GridAttribute); None for
              a mesh. The mesh is then the grids' boundary (voxel blocks around their
              active voxels: addon/volumegrids.py)
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None
    colors: np.ndarray | None = None
    coordinates: dict | None = None
    materials: list[str] = field(default_factory=lambda: ["default"])
    material_ids: np.ndarray | None = None
    visible_camera: bool = True
    visible_diffuse: bool = True
    visible_glossy: bool = True
    visible_transmission: bool = True
    visible_shadow: bool = True
    holdout: bool = False
    shadow_catcher: bool = False
    shadow_terminator_offset: float = 0.1
    shadow_terminator_shading_offset: float = 0.0
    cryptomatte_object: str | None = None
    cryptomatte_asset: str | None = None
    receivers: list | None = None
    non_receivers: list = field(default_factory=list)
    prototype: "Prototype | None" = None
    matrix: np.ndarray | None = None
    pass_index: int = 0
    random: float = 0.0
    object_color: tuple = (1.0, 1.0, 1.0, 1.0)
    location: tuple = (0.0, 0.0, 0.0)
    object_linear: tuple | None = None
    object_attributes: dict | None = None
    # Blender's Object > Shading > Light Group (engine/lightgroups.py): the light group
    # its materials' emission (surface and volume) goes to; "" none.
    lightgroup: str = ""
    volume_grids: dict | None = None
    warnings: list = field(default_factory=list, repr=False)

    @property
    def visibility(self) -> int:
        """Ray-class bits (engine.geometry CAMERA | DIFFUSE | GLOSSY | TRANSMISSION |
        SHADOW) of the rays that see this mesh."""
        bits = 0
        for bit, flag in ((1, self.visible_camera), (2, self.visible_diffuse),
                          (4, self.visible_glossy), (8, self.visible_transmission),
                          (16, self.visible_shadow)):
            bits |= bit if flag else 0
        return bits

    def __post_init__(self):
        who = f"mesh '{self.name}'"
        for attr in ("visible_camera", "visible_diffuse", "visible_glossy",
                     "visible_transmission", "visible_shadow", "holdout", "shadow_catcher"):
            setattr(self, attr, bool(getattr(self, attr)))
        try:
            sto = float(self.shadow_terminator_offset)
        except (TypeError, ValueError):
            sto = float("nan")
        if not (math.isfinite(sto) and sto >= 0):
            raise SceneError(f"{who}: shadow_terminator_offset must be a number >= 0, "
                             f"got {self.shadow_terminator_offset!r}")
        self.shadow_terminator_offset = sto
        try:
            sso = float(self.shadow_terminator_shading_offset)
        except (TypeError, ValueError):
            sso = float("nan")
        if not (math.isfinite(sso) and 0 <= sso < 2):
            raise SceneError(f"{who}: shadow_terminator_shading_offset must be a number in "
                             f"[0, 2), got {self.shadow_terminator_shading_offset!r}")
        self.shadow_terminator_shading_offset = sso
        if isinstance(self.materials, str):
            self.materials = [self.materials]
        if self.vertices is None:
            self._init_placement(who)
            return
        v = np.asarray(self.vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3:
            raise SceneError(f"{who}: vertices must have shape (V,3), got {v.shape}")
        f = np.asarray(self.faces)
        if f.size == 0:
            f = f.reshape(0, 3)
        if f.ndim != 2 or f.shape[1] != 3:
            raise SceneError(f"{who}: faces must have shape (F,3) (triangles), got {f.shape}")
        if not np.issubdtype(f.dtype, np.integer):
            if not np.all(np.isfinite(f)) or not np.all(f == np.round(f)):
                raise SceneError(f"{who}: face indices must be integers")
        f = f.astype(np.int64)
        nf = len(f)
        if self.material_ids is None:
            mids = np.zeros(nf, dtype=np.int32)
        else:
            mids = np.asarray(self.material_ids).astype(np.int64).reshape(-1)
            if mids.shape != (nf,):
                raise SceneError(f"{who}: material_ids must have one entry per face ({nf}), "
                                 f"got {mids.shape}")
            if nf and (mids.min() < 0 or mids.max() >= len(self.materials)):
                raise SceneError(f"{who}: material_ids out of range 0..{len(self.materials) - 1}")
            mids = mids.astype(np.int32)
        normals = None if self.normals is None else np.asarray(self.normals, dtype=np.float64)
        if normals is not None and normals.shape not in ((len(v), 3), (nf, 3, 3)):
            raise SceneError(f"{who}: normals must be (V,3) or (F,3,3), got {normals.shape}")
        uvs = None if self.uvs is None else np.asarray(self.uvs, dtype=np.float64)
        if uvs is not None and uvs.shape not in ((len(v), 2), (nf, 3, 2)):
            raise SceneError(f"{who}: uvs must be (V,2) or (F,3,2), got {uvs.shape}")
        colors = None if self.colors is None else np.asarray(self.colors, dtype=np.float64)
        if colors is not None:
            if colors.shape[:-1] not in ((len(v),), (nf, 3)) or colors.shape[-1] not in (3, 4):
                raise SceneError(f"{who}: colors must be (V,3|4) or (F,3,3|4), "
                                 f"got {colors.shape}")
            colors = np.nan_to_num(colors[..., :3], nan=0.0, posinf=1.0, neginf=0.0)
        coords = {}
        for key, arr in (self.coordinates or {}).items():
            arr = np.asarray(arr, dtype=np.float64)
            if arr.shape != (nf, 3, 3):
                raise SceneError(f"{who}: coordinates['{key}'] must be (F,3,3), got {arr.shape}")
            coords[str(key)] = np.nan_to_num(arr, nan=0.0, posinf=0.0, neginf=0.0)

        # Repairable defects: drop the faces, say how many and why.
        keep = np.ones(nf, dtype=bool)
        bad_index = np.any((f < 0) | (f >= len(v)), axis=1)
        if bad_index.any():
            self.warnings.append(f"{who}: dropped {int(bad_index.sum())} faces with vertex "
                                 f"indices outside 0..{len(v) - 1}")
            keep &= ~bad_index
        fi = np.where(keep[:, None], f, 0)
        if len(v):
            finite_v = np.all(representable(v), axis=1)
            bad_v = ~np.all(finite_v[fi], axis=1) & keep
            if bad_v.any():
                self.warnings.append(f"{who}: dropped {int(bad_v.sum())} faces that use "
                                     "NaN or infinite vertex coordinates (or beyond "
                                     "float32's +-3.4e38)")
                keep &= ~bad_v
            vv = np.where(representable(v), v, 0.0)
            e1 = vv[fi[:, 1]] - vv[fi[:, 0]]
            e2 = vv[fi[:, 2]] - vv[fi[:, 0]]
            area2 = np.linalg.norm(np.cross(e1, e2), axis=1)
            scale = np.maximum(np.linalg.norm(e1, axis=1), np.linalg.norm(e2, axis=1))
            degenerate = (area2 <= 1e-12 * np.maximum(scale * scale, 1e-300)) & keep
            if degenerate.any():
                self.warnings.append(f"{who}: dropped {int(degenerate.sum())} zero-area faces")
                keep &= ~degenerate
        if normals is not None:
            normals = np.nan_to_num(normals, nan=0.0, posinf=0.0, neginf=0.0)
        if uvs is not None:
            uvs = np.nan_to_num(uvs, nan=0.0, posinf=0.0, neginf=0.0)
        if not keep.all():
            f = f[keep]
            mids = mids[keep]
            if normals is not None and normals.ndim == 3:
                normals = normals[keep]
            if uvs is not None and uvs.ndim == 3:
                uvs = uvs[keep]
            if colors is not None and colors.ndim == 3:
                colors = colors[keep]
            coords = {k: a[keep] for k, a in coords.items()}
        self.vertices = np.where(representable(v), v, 0.0)  # unused bad ones: Embree needs all finite
        self.faces = f
        self.material_ids = mids
        self.normals = normals
        self.uvs = uvs
        self.colors = colors
        self.coordinates = coords or None
        if self.prototype is not None or self.matrix is not None:
            self._check_instance(who)

    def _check_instance(self, who: str):
        if not isinstance(self.prototype, Prototype):
            raise SceneError(f"{who}: prototype must be an engine.scene.Prototype, got "
                             f"{type(self.prototype).__name__}")
        m = np.asarray(self.matrix if self.matrix is not None else np.eye(4), np.float64)
        if m.shape not in ((4, 4), (3, 4)) or not np.all(np.isfinite(m)):
            raise SceneError(f"{who}: matrix must be a finite (4,4) or (3,4) array, got "
                             f"shape {m.shape}")
        self.matrix = np.ascontiguousarray(m[:3])

    def _init_placement(self, who: str):
        """A placement without a world-space copy (vertices=None): checks the record and
        takes the prototype's faces and material slots."""
        if self.prototype is None:
            raise SceneError(f"{who}: vertices are required (None only with a prototype)")
        for attr in ("faces", "normals", "uvs", "colors", "coordinates", "material_ids"):
            if getattr(self, attr) is not None:
                raise SceneError(f"{who}: a placement (vertices=None) takes its {attr} "
                                 "from its prototype; give them to the Prototype")
        self._check_instance(who)
        P = self.prototype
        n_slots = int(P.material_ids.max()) + 1 if len(P.material_ids) else 1
        if len(self.materials) < n_slots:
            raise SceneError(f"{who}: prototype '{P.name}' uses {n_slots} material slots, "
                             f"the placement names {len(self.materials)} materials")
        self.faces = P.placed_faces(np.linalg.det(self.matrix[:, :3]) < 0)
        self.material_ids = P.material_ids

    @property
    def copyless(self) -> bool:
        """True for a placement without a world-space copy (vertices None)."""
        return self.vertices is None

    @classmethod
    def place(cls, name: str, prototype: "Prototype", matrix, **kw) -> "Mesh":
        """A placement of `prototype` by the (4,4) or (3,4) object-to-world `matrix`
        without a world-space copy; kw: materials (the prototype's slots), visibility
        flags, holdout, shadow terminator offsets."""
        return cls(name, None, None, prototype=prototype, matrix=matrix, **kw)

    def expanded(self) -> "Mesh":
        """This mesh with a world-space copy (itself when it has one): vertices placed by
        the matrix, normals by its inverse transpose, per-corner values in the copy's
        corner order (0, 2, 1 when the matrix mirrors)."""
        if not self.copyless:
            return self
        P, M = self.prototype, self.matrix
        flip = np.linalg.det(M[:, :3]) < 0
        v, f = place(P, M)

        def corners(x):
            return None if x is None else (x[:, [0, 2, 1]] if flip and x.ndim == 3 else x)
        normals = None
        if P.normals is not None:
            normals = P.normals @ np.linalg.inv(M[:, :3])
            normals /= np.maximum(np.linalg.norm(normals, axis=-1, keepdims=True), 1e-300)
            normals = corners(normals)
        flags = {k: getattr(self, k) for k in (
            "visible_camera", "visible_diffuse", "visible_glossy", "visible_transmission",
            "visible_shadow", "holdout", "shadow_catcher", "shadow_terminator_offset",
            "shadow_terminator_shading_offset", "cryptomatte_object", "cryptomatte_asset",
            "pass_index", "random", "object_color", "location", "object_linear",
            "object_attributes", "receivers", "non_receivers", "lightgroup")}
        return Mesh(self.name, v, f, normals=normals, uvs=corners(P.uvs),
                    materials=list(self.materials), material_ids=P.material_ids,
                    prototype=P, matrix=M, **flags)

    def instance_matches(self) -> bool:
        """True when vertices and faces are the prototype placed by matrix (faces equal,
        or with corners 0, 2, 1 when the matrix mirrors; vertices within float64
        rounding of the transform), so tracing the prototype gives this mesh's hits.
        A placement without a copy always matches."""
        p = self.prototype
        if p is not None and self.copyless:
            return True
        if p is None or len(p.faces) != len(self.faces) or len(p.vertices) != len(self.vertices):
            return False
        flip = np.linalg.det(self.matrix[:, :3]) < 0
        if not np.array_equal(self.faces, p.faces[:, [0, 2, 1]] if flip else p.faces):
            return False
        w = p.vertices @ self.matrix[:, :3].T + self.matrix[:, 3]
        scale = max(float(np.abs(w).max(initial=0.0)), 1e-300)
        return bool(np.all(np.abs(w - self.vertices) <= 1e-9 * scale))


def place(prototype: "Prototype", matrix) -> tuple[np.ndarray, np.ndarray]:
    """World-space vertices (V,3) and faces (F,3) of `prototype` placed by the (4,4) or
    (3,4) object-to-world `matrix`, as Mesh.prototype expects them (corners 0, 2, 1 when
    the matrix mirrors, so the winding stays outward)."""
    m = np.asarray(matrix, np.float64)[:3]
    faces = prototype.faces[:, [0, 2, 1]] if np.linalg.det(m[:, :3]) < 0 else prototype.faces
    return prototype.vertices @ m[:, :3].T + m[:, 3], faces


@dataclass(eq=False)
class Prototype:
    """Object-space triangles shared by instances (Mesh.prototype): vertices (V,3),
    faces (F,3) int; optional object-space normals ((V,3) or (F,3,3)), uvs ((V,2) or
    (F,3,2)) and material_ids (F,) (material slots; the placements name the materials),
    which placements without a copy (Mesh.place) use. Faces a Mesh would drop (indices
    out of range, NaN corners, zero area) are dropped here too, so an instance's faces
    equal the prototype's."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None
    material_ids: np.ndarray | None = None

    def __post_init__(self):
        slots = 1
        if self.material_ids is not None and np.size(self.material_ids):
            slots = int(np.max(self.material_ids)) + 1
        clean = Mesh(name=f"prototype '{self.name}'", vertices=self.vertices, faces=self.faces,
                     normals=self.normals, uvs=self.uvs, material_ids=self.material_ids,
                     materials=[f"slot {i}" for i in range(max(slots, 1))])
        self.vertices, self.faces = clean.vertices, clean.faces
        self.normals, self.uvs, self.material_ids = clean.normals, clean.uvs, clean.material_ids
        self.warnings = clean.warnings
        self._flipped = None

    def placed_faces(self, flip: bool) -> np.ndarray:
        """The faces of a placement: the prototype's, or (shared between all mirrored
        placements) with corners 0, 2, 1."""
        if not flip:
            return self.faces
        if self._flipped is None:
            self._flipped = np.ascontiguousarray(self.faces[:, [0, 2, 1]])
        return self._flipped


@dataclass
class Light:
    """A light with Blender/Cycles units (docs/units.md).

    kind      POINT, SPOT, AREA or SUN
    power     watts for point/spot/area (total emitted flux), W/m^2 irradiance for sun
    color     RGB multiplier of power
    position  world position (ignored for SUN)
    direction the light's local -Z axis in world space (spot axis, area normal, sun rays)
    radius    point/spot soft-shadow radius (Blender `shadow_soft_size`)
    soft_falloff  point/spot with a radius: True (Blender's "Soft Falloff", its default)
              is Cycles' disk of that radius facing the shading point, whose light fades
              towards a surface it nearly touches; False is a true sphere of that radius
              (Cycles' `is_sphere`: kernel/light/point.h, spot.h), brighter up close
    spot_size full cone angle in radians; spot_blend 0..1
    shape     RECTANGLE or DISK for area lights; size_x, size_y in world units (already
              multiplied by object scale); axis_u gives the local +X direction
    skew_axis_v  optional local +Y direction of a sheared area light (not perpendicular to
              axis_u). As in Cycles, the emitter is then the region |p.u| <= size_x/2,
              |p.v| <= size_y/2 of its plane (a parallelogram; for DISK the ellipse
              (2 p.u / size_x)^2 + (2 p.v / size_y)^2 <= 1), of area size_x size_y / sin(u, v),
              and its radiance stays P / (pi size_x size_y) as Cycles computes it.
    angle     sun angular diameter in radians
    normalize area light power divided by area (Blender default True)
    spread    area light: full angle in radians of its emission cone (Blender `spread`,
              default pi = Lambertian); narrower spreads attenuate as Cycles' soft-box grid
    visible_camera  lights are invisible to camera rays by default in Blender
    visible_diffuse, visible_glossy, visible_transmission  the light object's ray
              visibility with Cycles' meaning: diffuse off, no diffuse surface receives it
              (no shadow-ray light, no direct photons, no photon that bounces diffusely at
              its first hit); glossy / transmission off, not seen in mirrors / through glass
              and no photon continues from it through a mirror / glass at its first hit
    cast_shadow  Blender's light 'Cast Shadow' (use_shadow): off, no object blocks the
              light's shadow rays (its direct light); photons are still blocked
    receivers  Light Linking (Blender 4.0+ Object > Shading > Light Linking, as Cycles
              renders it): None, the light lights every object; a list of mesh names, it
              lights only those (directly: shadow rays, the photons' first hit, its surface
              seen in a mirror the path left); engine/lightlinking.py
    non_receivers  mesh names the light does not light directly (the exclude form;
              ignored for names also in receivers)
    blockers  Shadow Linking (Blender 4.0+, Object > Shading > Shadow Linking): None,
              every object casts the light's shadows; a list of mesh names, only those do
              (its shadow rays pass the others, and its photons reach what lies behind
              them: engine/lightlinking.py)
    non_blockers  mesh names that cast none of the light's shadows (the exclude form)
    ies_path  point/spot: an IES (LM-63) profile file read into ies_profile (engine/ies.py:
              the emitted intensity along w is power x color / (4 pi) x f(w) in the lamp's
              frame, as Cycles' IES Texture on the Emission Strength); ies_profile an
              ies.IESProfile given directly (the add-on's text datablocks)
    spot_frame optional (3,3): rows map a world direction leaving a spot light into its
              cone space, where the cone is round: Cycles' scaled_axis_u, scaled_axis_v and
              dir * inv_len_z (the light object's X and Y axes divided by their squared
              length, its -Z axis divided by its length). An object scale (2, 0.5, 1) thus
              stretches the lit spot 2x along X and halves it along Y (Cycles >= 3.5,
              kernel/light/spot.h). None: the round cone of (axis_u, axis_v, direction).
    """

    name: str = "light"
    kind: str = POINT
    power: float = 100.0
    color: tuple | np.ndarray = (1.0, 1.0, 1.0)
    position: tuple | np.ndarray = (0.0, 0.0, 0.0)
    direction: tuple | np.ndarray = (0.0, 0.0, -1.0)
    axis_u: tuple | np.ndarray = (1.0, 0.0, 0.0)
    radius: float = 0.0
    soft_falloff: bool = True
    spot_size: float = math.radians(45.0)
    spot_blend: float = 0.15
    shape: str = RECTANGLE
    size_x: float = 1.0
    size_y: float = 1.0
    angle: float = 0.0
    normalize: bool = True
    spread: float = math.pi
    visible_camera: bool = False
    visible_diffuse: bool = True
    visible_glossy: bool = True
    visible_transmission: bool = True
    cast_shadow: bool = True
    receivers: list | None = None
    non_receivers: list = field(default_factory=list)
    blockers: list | None = None
    non_blockers: list = field(default_factory=list)
    spot_frame: np.ndarray | None = None
    skew_axis_v: tuple | np.ndarray | None = None
    ies_path: str | None = None
    ies_profile: object = None
    # Blender's Object > Shading > Light Group (engine/lightgroups.py): the light group
    # whose pass its light goes to; "" none.
    lightgroup: str = ""
    warnings: list = field(default_factory=list, repr=False)

    def __post_init__(self):
        who = f"light '{self.name}'"
        self.kind = str(self.kind).upper()
        from .lights import DECLARED_KINDS  # the registry imports this module
        if self.kind not in DECLARED_KINDS:
            raise SceneError(f"{who}: unknown kind '{self.kind}' ({', '.join(DECLARED_KINDS)})")
        self.shape = {"SQUARE": RECTANGLE, "ELLIPSE": DISK}.get(str(self.shape).upper(),
                                                                 str(self.shape).upper())
        if self.shape not in (RECTANGLE, DISK):
            raise SceneError(f"{who}: unknown area shape '{self.shape}'")
        self.color = _vec3(self.color, f"{who} color")
        if np.any(self.color < 0):
            raise SceneError(f"{who} color: must be >= 0")
        self.position = _vec3(self.position, f"{who} position")
        d = _vec3(self.direction, f"{who} direction")
        n = np.linalg.norm(d)
        if n < 1e-12:
            raise SceneError(f"{who} direction: must not be the zero vector")
        self.direction = d / n
        u = _vec3(self.axis_u, f"{who} axis_u")
        u = u - self.direction * np.dot(u, self.direction)
        if np.linalg.norm(u) < 1e-9:  # pick any perpendicular axis
            u = np.cross(self.direction, [1.0, 0.0, 0.0])
            if np.linalg.norm(u) < 1e-6:
                u = np.cross(self.direction, [0.0, 1.0, 0.0])
        self.axis_u = u / np.linalg.norm(u)
        if self.skew_axis_v is not None:
            v = _vec3(self.skew_axis_v, f"{who} skew_axis_v")
            v = v - self.direction * np.dot(v, self.direction)
            if np.linalg.norm(np.cross(self.axis_u, v)) < 1e-6 * max(np.linalg.norm(v), 1e-300):
                raise SceneError(f"{who} skew_axis_v: parallel to axis_u (degenerate shear)")
            v = v / np.linalg.norm(v)
            self.skew_axis_v = None if abs(np.dot(v, self.axis_u)) < 1e-9 else v
        for attr in ("power", "radius", "spot_size", "spot_blend", "size_x", "size_y", "angle",
                     "spread"):
            setattr(self, attr, _finite(getattr(self, attr), f"{who} {attr}"))
        if self.power < 0:
            raise SceneError(f"{who} power: must be >= 0, got {self.power}")
        self.radius = max(self.radius, 0.0)
        self.soft_falloff = bool(self.soft_falloff)
        for attr in ("receivers", "blockers"):
            if getattr(self, attr) is not None:
                setattr(self, attr, _names(getattr(self, attr), f"{who} {attr}"))
            setattr(self, "non_" + attr, _names(getattr(self, "non_" + attr),
                                                f"{who} non_{attr}"))
        self.size_x, self.size_y = abs(self.size_x), abs(self.size_y)
        self.spot_size = min(max(self.spot_size, 1e-4), math.pi)
        self.spot_blend = min(max(self.spot_blend, 0.0), 1.0)
        self.angle = min(max(self.angle, 0.0), math.pi)
        if not 0.0 <= self.spread <= math.pi + 1e-6:
            raise SceneError(f"{who} spread: must be in [0, 180] degrees, got "
                             f"{math.degrees(self.spread):.1f}")
        if self.spread < MIN_SPREAD:
            # Cycles' spread 0 is a collimated beam (a delta in direction) that no shadow
            # ray can find; the narrowest cone we sample keeps the power and the look.
            self.warnings.append(f"{who}: spread {math.degrees(self.spread):.2f} deg is "
                                 f"rendered as {math.degrees(MIN_SPREAD):.1f} deg")
            self.spread = MIN_SPREAD
        self.spread = min(self.spread, math.pi)
        if self.spot_frame is not None:
            frame = np.asarray(self.spot_frame, dtype=np.float64)
            if frame.shape != (3, 3) or not np.all(np.isfinite(frame)):
                raise SceneError(f"{who} spot_frame: expected a finite 3x3 matrix, "
                                 f"got shape {frame.shape}")
            if abs(np.linalg.det(frame)) < 1e-12 * max(np.abs(frame).max(), 1e-300) ** 3:
                raise SceneError(f"{who} spot_frame: singular matrix (zero scale?)")
            self.spot_frame = frame
        if self.kind == AREA and self.size_x * self.size_y <= 0:
            self.warnings.append(f"{who}: area light of zero size emits nothing")
        self._load_ies(who)

    def _load_ies(self, who):
        """ies_profile from ies_path (engine/ies.py); a broken file or a light kind that
        takes none: a warning, and the plain light renders."""
        if self.ies_profile is None and self.ies_path:
            from .ies import IESError, load
            try:
                self.ies_profile = load(str(self.ies_path))
            except IESError as e:
                self.warnings.append(f"{who}: IES profile not used, the plain light renders "
                                     f"({e})")
        if self.ies_profile is not None and self.kind not in (POINT, SPOT):
            self.warnings.append(f"{who}: IES profiles apply to point and spot lights; "
                                 f"ignored on a {self.kind.lower()} light")
            self.ies_profile = None

    @property
    def cone_frame(self) -> np.ndarray:
        """(3,3) rows taking world directions into the spot's round-cone space."""
        if self.spot_frame is not None:
            return self.spot_frame
        return np.stack([self.axis_u, self.axis_v, self.direction])

    @property
    def axis_v(self) -> np.ndarray:
        if self.skew_axis_v is not None:
            return self.skew_axis_v
        # Right-handed local frame: u x v = +Z = -direction.
        return np.cross(-self.direction, self.axis_u)

    @property
    def sin_uv(self) -> float:
        """Sine of the angle between axis_u and axis_v (1 unless sheared)."""
        if self.skew_axis_v is None:
            return 1.0
        return float(np.linalg.norm(np.cross(self.axis_u, self.skew_axis_v)))

    @property
    def area(self) -> float:
        a = self.size_x * self.size_y / self.sin_uv
        return a * math.pi / 4.0 if self.shape == DISK else a

    @property
    def flux(self) -> np.ndarray:
        """Total emitted RGB flux in watts (sun: per m^2 of its beam)."""
        p = self.power * self.color
        if self.kind == SPOT:
            # Cycles spot = point light masked by the cone (no renormalisation):
            # flux = I * solid angle with smoothstep falloff, integrated numerically.
            if self.spot_frame is None:
                return p * spot_cone_fraction(self.spot_size, self.spot_blend)
            return p * spot_cone_fraction_frame(self.spot_size, self.spot_blend,
                                                self.cone_frame, self.direction)
        if self.kind == AREA and not self.normalize:
            return p * self.area  # power given per unit area
        if self.kind == AREA:
            # Cycles divides the power by size_x * size_y even when shear makes the
            # emitter larger (scene/light.cpp: invarea from len_u * len_v).
            return p / self.sin_uv
        return p


def spread_attenuation(cos_a, spread: float):
    """Cycles' area-light spread (kernel/light/area.h, area_light_spread_attenuation; the
    soft-box grid of Blender D10594): radiance leaving at angle a from the light's axis is
    scaled by max((tan h - tan a) * N, 0), h = spread / 2, N = 1 / (tan h - h) (3 / h^3 for
    small h, as Cycles' scene/light.cpp). N makes the emitted flux independent of the
    spread: integral over the hemisphere of f(a) cos a dw = pi. Returns an array like cos_a
    (1 where spread is pi)."""
    cos_a = np.asarray(cos_a, np.float64)
    if spread >= math.pi - 1e-6:
        return np.ones_like(cos_a)
    h = 0.5 * spread
    tan_h = math.tan(h)
    norm = 1.0 / (tan_h - h) if h > 0.05 else 3.0 / h ** 3
    c = np.maximum(cos_a, 1e-12)
    tan_a = np.sqrt(np.maximum(1.0 - c * c, 0.0)) / c
    return np.where(cos_a > 0, np.maximum((tan_h - tan_a) * norm, 0.0), 0.0)


def spot_mask(cos_theta, spot_size: float, spot_blend: float):
    """Cycles' spot falloff: smoothstep of the cosine inside the cone."""
    cos_half = math.cos(spot_size / 2.0)
    width = (1.0 - cos_half) * spot_blend
    x = np.asarray(cos_theta, dtype=np.float64) - cos_half
    if width <= 0:
        return (x > 0).astype(np.float64)
    f = np.clip(x / width, 0.0, 1.0)
    return f * f * (3.0 - 2.0 * f)


def spot_cone_fraction(spot_size: float, spot_blend: float) -> float:
    """Fraction of a point light's 4*pi*I flux that leaves through the spot's mask."""
    cos_half = math.cos(spot_size / 2.0)
    c = np.linspace(cos_half, 1.0, 4097)
    m = spot_mask(c, spot_size, spot_blend)
    # Solid angle element 2*pi*d(cos); fraction of the 4*pi sphere.
    return float(np.trapz(m, c) * 2.0 * math.pi / (4.0 * math.pi))


def spot_cone_cos(w, frame: np.ndarray) -> np.ndarray:
    """Cosine to the axis of the round cone, for world directions w (N,3) leaving the
    light, after the spot's frame (Light.cone_frame) has undone its object scale: the
    z component of normalize(frame @ w), as Cycles' spot_light_to_local."""
    local = np.asarray(w, dtype=np.float64) @ np.asarray(frame, dtype=np.float64).T
    length = np.sqrt(local[:, 0] ** 2 + local[:, 1] ** 2 + local[:, 2] ** 2)
    return local[:, 2] / np.maximum(length, 1e-300)


def spot_bounding_cos(spot_size: float, frame: np.ndarray, direction: np.ndarray) -> float:
    """Cosine of a cone round `direction` that holds the whole (elliptical) lit cone."""
    frame = np.asarray(frame, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    gram = frame @ frame.T
    if (np.allclose(gram, np.eye(3) * gram[0, 0], rtol=0, atol=1e-9 * gram[0, 0])
            and np.allclose(frame[2] / np.linalg.norm(frame[2]), d / np.linalg.norm(d),
                            rtol=0, atol=1e-9)):
        return math.cos(spot_size / 2.0)  # round cone: exact
    h = min(spot_size / 2.0, math.pi / 2.0)
    phi = np.linspace(0.0, 2.0 * math.pi, 721)
    # Boundary directions in cone space, taken back to world space.
    edge = np.stack([math.sin(h) * np.cos(phi), math.sin(h) * np.sin(phi),
                     np.full_like(phi, math.cos(h))], axis=1)
    w = edge @ np.linalg.inv(frame).T
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    c = float(np.min(w @ (d / np.linalg.norm(d))))
    if c <= 0.0:
        return -1.0  # the cone reaches behind the light: bound it by the whole sphere
    # Widen by 1 % in tan so the bound holds between the 721 boundary samples.
    tan = math.sqrt(max(1.0 - c * c, 0.0)) / c * 1.01
    return 1.0 / math.sqrt(1.0 + tan * tan)


def spot_cone_fraction_frame(spot_size: float, spot_blend: float, frame: np.ndarray,
                             direction: np.ndarray) -> float:
    """spot_cone_fraction for a scaled (elliptical) cone: 2-D quadrature of the mask over
    the bounding cone (midpoint rule, 1024 x 256 cells)."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    t = np.cross(d, [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0])
    t /= np.linalg.norm(t)
    b = np.cross(d, t)
    c0 = spot_bounding_cos(spot_size, frame, d)
    nc, nphi = 1024, 256
    c = c0 + (np.arange(nc) + 0.5) / nc * (1.0 - c0)
    phi = (np.arange(nphi) + 0.5) / nphi * 2.0 * math.pi
    s = np.sqrt(np.maximum(1.0 - c * c, 0.0))
    w = (c[:, None, None] * d + (s[:, None] * np.cos(phi))[:, :, None] * t
         + (s[:, None] * np.sin(phi))[:, :, None] * b).reshape(-1, 3)
    m = spot_mask(spot_cone_cos(w, frame), spot_size, spot_blend)
    solid = 2.0 * math.pi * (1.0 - c0)
    return float(m.mean() * solid / (4.0 * math.pi))


@dataclass
class LightPortal:
    """A Cycles light portal (an Area light with Portal on: Light > Cycles > Portal): a
    rectangle over an opening that emits nothing and tells where the world's light enters
    a room. corners (4,3) world space (m), in order round the rectangle; normal (3,) unit,
    the light's local -Z: into the room; round: a Disk / Ellipse portal (Cycles'
    is_round), the ellipse inscribed in the rectangle. Cycles samples the background
    through it; here the world's shadow rays (lights/world.py) and the world's and suns'
    photons (engine/portal.py) may too."""

    name: str
    corners: np.ndarray
    normal: np.ndarray
    round: bool = False

    def __post_init__(self):
        self.corners = np.asarray(self.corners, np.float64).reshape(4, 3)
        n = np.asarray(self.normal, np.float64).reshape(3)
        norm = float(np.linalg.norm(n))
        if not (np.all(np.isfinite(self.corners)) and norm > 0.0 and math.isfinite(norm)):
            raise SceneError(f"light portal '{self.name}': corners and normal must be "
                             "finite, the normal non-zero")
        self.normal = n / norm
        self.round = bool(self.round)


@dataclass
class Camera:
    """Pinhole, orthographic or panoramic camera, Blender conventions.

    position, and a rotation whose columns are the camera's right (x), up (y) and back
    (z) axes in world space: the camera looks along -z. `fov` is the full angle across the
    larger image dimension (Blender's sensor fit AUTO); `ortho_scale` likewise in world
    units. shift_x / shift_y are in units of the larger image dimension (as Blender's);
    a panoramic camera's (kind "PANO") in units of the image's width and height, as
    Cycles adds them to its image coordinates. `panorama`: the engine.panorama.Panorama
    of a PANO camera (a dict of its fields is taken too; None: an equirectangular one).
    """

    position: tuple | np.ndarray = (0.0, 0.0, 5.0)
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    fov: float = math.radians(39.6)
    kind: str = "PERSP"
    ortho_scale: float = 7.0
    shift_x: float = 0.0
    shift_y: float = 0.0
    sensor_fit: str = "AUTO"  # AUTO (larger dimension), HORIZONTAL or VERTICAL
    clip_start: float = 0.0
    clip_end: float = float("inf")
    # Depth of field (thin lens, Cycles): aperture radius (m; ORTHO: world units as
    # Cycles' 1 / (2 f-stop)), 0 = pinhole; focus_distance (m) along the view axis;
    # aperture_blades >= 3 a polygonal aperture (else round), aperture_rotation (rad),
    # aperture_ratio (Blender's: > 1 squeezes the bokeh horizontally).
    aperture_radius: float = 0.0
    focus_distance: float = 10.0
    aperture_blades: int = 0
    aperture_rotation: float = 0.0
    aperture_ratio: float = 1.0
    panorama: Panorama | None = None

    def __post_init__(self):
        self.position = _vec3(self.position, "camera position")
        r = np.asarray(self.rotation, dtype=np.float64)
        if r.shape != (3, 3) or not np.all(np.isfinite(r)):
            raise SceneError(f"camera rotation: expected a finite 3x3 matrix, got {r.shape}")
        # Orthonormalise (exporters may pass scaled matrices).
        x = r[:, 0] / max(np.linalg.norm(r[:, 0]), 1e-300)
        z = r[:, 2] - x * np.dot(r[:, 2], x)
        z /= max(np.linalg.norm(z), 1e-300)
        y = np.cross(z, x)
        self.rotation = np.stack([x, y, z], axis=1)
        self.kind = str(self.kind).upper()
        if self.kind not in ("PERSP", "ORTHO", "PANO"):
            raise SceneError(f"camera kind: must be PERSP, ORTHO or PANO, got {self.kind}")
        if self.kind == "PANO":
            try:
                if self.panorama is None:
                    self.panorama = Panorama()
                elif isinstance(self.panorama, dict):
                    self.panorama = Panorama(**self.panorama)
                elif not isinstance(self.panorama, Panorama):
                    raise ValueError("expected an engine.panorama.Panorama, got "
                                     f"{type(self.panorama).__name__}")
            except (TypeError, ValueError) as exc:
                raise SceneError(f"camera panorama: {exc}") from None
        else:
            self.panorama = None
        self.fov = min(max(_finite(self.fov, "camera fov"), 1e-6), math.pi - 1e-6)
        self.ortho_scale = _finite(self.ortho_scale, "camera ortho_scale")
        if self.ortho_scale <= 0:
            raise SceneError("camera ortho_scale: must be > 0")
        self.shift_x = _finite(self.shift_x, "camera shift_x")
        self.shift_y = _finite(self.shift_y, "camera shift_y")
        self.sensor_fit = str(self.sensor_fit).upper()
        self.clip_start = max(float(self.clip_start), 0.0)
        self.clip_end = float(self.clip_end) if self.clip_end > 0 else float("inf")
        self.aperture_radius = _finite(self.aperture_radius, "camera aperture_radius")
        if self.aperture_radius < 0:
            raise SceneError("camera aperture_radius: must be >= 0 (0: pinhole)")
        self.focus_distance = _finite(self.focus_distance, "camera focus_distance")
        if self.focus_distance <= 0:
            raise SceneError("camera focus_distance: must be > 0")
        blades = int(self.aperture_blades)
        self.aperture_blades = blades if blades >= 3 else 0
        self.aperture_rotation = _finite(self.aperture_rotation, "camera aperture_rotation")
        self.aperture_ratio = _finite(self.aperture_ratio, "camera aperture_ratio")
        if self.aperture_ratio <= 0:
            raise SceneError("camera aperture_ratio: must be > 0")

    @property
    def has_dof(self) -> bool:
        """Whether rays start on a lens (aperture_radius > 0) rather than at a pinhole."""
        return self.aperture_radius > 0.0

    @classmethod
    def look_at(cls, position, look_at, up=(0.0, 0.0, 1.0), fov_degrees=40.0, **kw):
        """The paper's camera: position, look-at point, up vector, view angle (degrees)."""
        p = _vec3(position, "camera position")
        forward = _vec3(look_at, "camera look_at") - p
        if np.linalg.norm(forward) < 1e-12:
            raise SceneError("camera: look_at must differ from position")
        forward /= np.linalg.norm(forward)
        upv = _vec3(up, "camera up")
        x = np.cross(forward, upv)
        if np.linalg.norm(x) < 1e-9:
            x = np.cross(forward, [1.0, 0.0, 0.0] if abs(forward[0]) < 0.9 else [0.0, 1.0, 0.0])
        x /= np.linalg.norm(x)
        y = np.cross(x, forward)
        rot = np.stack([x, y, -forward], axis=1)
        return cls(position=p, rotation=rot, fov=math.radians(fov_degrees), **kw)

    def half_extents(self, width: int, height: int) -> tuple[float, float]:
        """Half width and height of the image plane at distance 1 (ortho: world units;
        a panorama: half its pixel angle (rad) times the image's width and height, so
        that 2 hw / width is the pixel's angular size, the ray footprint's measure)."""
        if self.panorama is not None:
            a = 0.5 * self.panorama.pixel_angle(width, height)
            return a * width, a * height
        aspect = width / height
        fit = self.sensor_fit
        if fit == "AUTO":
            fit = "HORIZONTAL" if width >= height else "VERTICAL"
        half = math.tan(self.fov / 2.0) if self.kind == "PERSP" else self.ortho_scale / 2.0
        if fit == "HORIZONTAL":
            return half, half / aspect
        return half * aspect, half


def _used_by(names, shown: int = 3) -> str:
    """' (used by 'A', 'B', 'C' and 2 more)' for a material warning; '' for no user."""
    names = list(names)
    if not names:
        return ""
    text = ", ".join(f"'{n}'" for n in names[:shown])
    if len(names) > shown:
        text += f" and {len(names) - shown} more"
    return f" (used by {text})"


@dataclass
class WorldMedium:
    """Blender's World > Volume: a homogeneous medium filling all space outside the
    objects' own media (Cycles: the world volume; Blender manual, World > Volume).
    `absorption` sigma_a (3,) and `scattering` sigma_s (3,) in 1/m per channel, and the
    Henyey-Greenstein `anisotropy` g in (-1, 1) of its scattering, as a material's medium
    (Material.absorption / scattering / anisotropy; addon/materials.py _volume reads the
    World Output's Volume as a Material Output's). The world lies infinitely far beyond
    it: a ray escaping the scene keeps exp(-sigma_t x infinity) = 0 of the world's light,
    so the world's surface (Background, HDRI) and sun lamps light nothing and the
    background reads black (engine/worldmedium.py). `emission` (3,) W m^-2 sr^-1 per
    metre: the radiance it emits per unit length (Material.volume_emission; a ray
    escaping through it collects e / sigma_t, engine/volumeemission.py)."""

    absorption: tuple | np.ndarray = (0.0, 0.0, 0.0)
    scattering: tuple | np.ndarray = (0.0, 0.0, 0.0)
    anisotropy: float = 0.0
    emission: tuple | np.ndarray = (0.0, 0.0, 0.0)

    def validate(self) -> None:
        self.absorption = _vec3(self.absorption, "world_medium absorption")
        self.scattering = _vec3(self.scattering, "world_medium scattering")
        if np.any(self.absorption < 0) or np.any(self.scattering < 0):
            raise SceneError("world_medium: absorption and scattering must be >= 0 (1/m), "
                             f"got {self.absorption.tolist()}, {self.scattering.tolist()}")
        self.emission = _vec3(self.emission, "world_medium emission")
        if np.any(self.emission < 0):
            raise SceneError("world_medium: emission must be >= 0 (W/m^2/sr per m), got "
                             f"{self.emission.tolist()}")
        self.anisotropy = float(self.anisotropy)
        if not -1.0 < self.anisotropy < 1.0:
            raise SceneError(f"world_medium anisotropy: must lie in (-1, 1), got "
                             f"{self.anisotropy}")

    @property
    def extinction(self) -> np.ndarray:
        """sigma_t = sigma_a + sigma_s (3,) 1/m."""
        return (np.asarray(self.absorption, np.float64)
                + np.asarray(self.scattering, np.float64))


@dataclass
class Scene:
    """All scene content. Build with the add_* methods (see engine.api for the paper's
    convenience calls) or assign lists directly; call validate() (render does)."""

    meshes: list[Mesh] = field(default_factory=list)
    materials: dict[str, Material] = field(default_factory=dict)
    lights: list[Light] = field(default_factory=list)
    camera: Camera | None = None
    width: int = 320
    height: int = 240
    background: tuple | np.ndarray = (0.0, 0.0, 0.0)
    background_is_light: bool = True
    # An equirectangular environment map (engine/lights/environment.py Environment); when
    # set it replaces `background` as the world's radiance.
    environment: object | None = None
    # What camera rays (and those passed on through transparent surfaces) see of the
    # world when it differs from what lights the scene: a world that mixes its shaders by
    # Light Path's Is Camera Ray (Cycles). None: `background` / `environment`, as every
    # other ray. camera_background (3,) RGB radiance; camera_environment an Environment
    # that replaces it (engine/worldmedium.background), or a worldgraph.WorldGraph (a
    # screen-mapped backplate: the world's nodes evaluated at each camera ray).
    camera_background: tuple | np.ndarray | None = None
    camera_environment: object | None = None
    # Blender's World > Mist Pass as Cycles' film reads it: (start m, depth m, falloff
    # exponent: 2 quadratic, 1 linear, 0.5 inverse quadratic); the default is Cycles'
    # Film's (a scene without a world), Blender's world default is (5, 25, 2).
    mist: tuple = (0.0, 100.0, 1.0)
    warnings: list = field(default_factory=list)
    # Cycles light portals (LightPortal): openings the world's light enters by.
    portals: list = field(default_factory=list)
    # Blender's World > Volume (WorldMedium, None: vacuum): a homogeneous medium filling
    # all space outside the objects' media (engine/worldmedium.py).
    world_medium: "WorldMedium | None" = None
    # The Vector pass' motion (engine/vectorpass.SceneMotion: the camera and each mesh's
    # object transform one frame before and after); None: nothing moves.
    vector_motion: "object | None" = None
    # Blender's World > Settings > Light Group (engine/lightgroups.py): the group the
    # world's light goes to; "" none.
    world_lightgroup: str = ""

    def add_material(self, material: Material) -> Material:
        self.materials[material.name] = material
        return material

    def add_mesh(self, mesh: Mesh) -> Mesh:
        self.meshes.append(mesh)
        return mesh

    def add_light(self, light: Light) -> Light:
        self.lights.append(light)
        return light

    def all_warnings(self) -> list[str]:
        """Every warning of the scene, its materials, meshes and lights, each once. A
        material's warnings end with the meshes that use it (a user looks for objects,
        not materials: "... (used by 'Suzanne', 'Cube')"), at most three named."""
        out = list(self.warnings)
        users = self._material_users() if any(
            m.warnings for m in self.materials.values()) else {}
        for m in self.materials.values():
            out += [w + _used_by(users.get(m.name, ())) for w in m.warnings]
        for m in self.meshes:
            out += m.warnings
        for light in self.lights:
            out += light.warnings
        seen, unique = set(), []
        for w in out:
            if w not in seen:
                seen.add(w)
                unique.append(w)
        return unique

    def _check_links(self) -> None:
        """Light / Shadow Linking names (Light.receivers, non_receivers, blockers,
        non_blockers) that name no mesh: a warning each (a receivers list of none of the
        scene's objects lights nothing)."""
        names = {m.name for m in self.meshes}
        for light in self.lights:
            for attr in ("receivers", "blockers"):
                if getattr(light, attr) is not None:
                    setattr(light, attr, _names(getattr(light, attr),
                                                f"light '{light.name}' {attr}"))
                setattr(light, "non_" + attr, _names(getattr(light, "non_" + attr),
                                                     f"light '{light.name}' non_{attr}"))
            for attr in ("receivers", "non_receivers", "blockers", "non_blockers"):
                for name in getattr(light, attr) or ():
                    if name not in names:
                        msg = (f"light '{light.name}': {attr} names '{name}', which is no "
                               "object of the scene; ignored")
                        if msg not in self.warnings:
                            self.warnings.append(msg)
        for mesh in self.meshes:
            if mesh.receivers is not None:
                mesh.receivers = _names(mesh.receivers, f"mesh '{mesh.name}' receivers")
            mesh.non_receivers = _names(mesh.non_receivers,
                                        f"mesh '{mesh.name}' non_receivers")

    def _material_users(self) -> dict[str, list[str]]:
        """Material name -> names of the meshes whose slots hold it (scene order)."""
        users: dict[str, list[str]] = {}
        for mesh in self.meshes:
            for name in dict.fromkeys(mesh.materials):
                users.setdefault(name, []).append(mesh.name)
        return users

    def validate(self) -> None:
        """Raise SceneError for what cannot render; warn (scene.warnings) for the rest."""
        self.width, self.height = int(self.width), int(self.height)
        if self.width < 1 or self.height < 1:
            raise SceneError(f"resolution must be at least 1x1, got {self.width}x{self.height}")
        if self.camera is None:
            raise SceneError("scene has no camera: add one (Camera.look_at(...))")
        self.background = _vec3(self.background, "background")
        if np.any(self.background < 0):
            raise SceneError("background: colour must be >= 0")
        for mesh in self.meshes:
            for name in mesh.materials:
                if name not in self.materials:
                    if name == "default":
                        self.materials["default"] = Material("default")
                    else:
                        raise SceneError(f"mesh '{mesh.name}': unknown material '{name}'")
        for name in ("environment", "camera_environment"):
            env = getattr(self, name)
            if env is not None:
                from .lights.environment import Environment
                from .worldgraph import WorldGraph
                # (camera rays may see a world graph evaluated per ray: a backplate)
                if not isinstance(env, (Environment, WorldGraph) if name ==
                                  "camera_environment" else Environment):
                    raise SceneError(f"{name}: expected an engine Environment, got "
                                     f"{type(env).__name__}")
        if self.camera_background is not None:
            self.camera_background = _vec3(self.camera_background, "camera_background")
            if np.any(self.camera_background < 0):
                raise SceneError("camera_background: radiance must be >= 0, got "
                                 f"{self.camera_background.tolist()}")
        if self.world_medium is not None:
            if not isinstance(self.world_medium, WorldMedium):
                raise SceneError(f"world_medium: expected an engine WorldMedium, got "
                                 f"{type(self.world_medium).__name__}")
            self.world_medium.validate()
            from .worldmedium import warnings_for
            for msg in warnings_for(self):
                if msg not in self.warnings:
                    self.warnings.append(msg)
        self._check_links()
        # (emitting media glow too: engine/volumeemission.py)
        has_emitter = any(m.is_emissive or np.any(m.volume_emission > 0)
                          or getattr(m, "volume_emission_texture", None) is not None
                          for m in self.materials.values())
        if self.world_medium is not None and np.any(self.world_medium.emission > 0):
            has_emitter = True
        world_lit = (not self.environment.is_black if self.environment is not None
                     else np.any(self.background > 0))
        if self.world_medium is not None and np.all(self.world_medium.extinction > 0):
            world_lit = False  # infinitely far beyond the world volume (worldmedium.py)
        if not self.lights and not has_emitter and not world_lit:
            msg = "scene has no lights, emissive materials or background light: image is black"
            if msg not in self.warnings:
                self.warnings.append(msg)
